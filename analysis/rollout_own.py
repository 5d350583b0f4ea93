# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A decentralised rollout planner (an experiment, outside the library)
#
# How much of `controller=rollout`'s gain over B's teacher survives when each agent plans on what it knows alone.
#
# The shipped planner is centralised: agent i's moves are played out in imagined copies of the whole world (every
# teammate's position, belief and rule) and scored under the team's posterior, the map of everything any agent has
# sensed. Here agent i plans on its own belief: the copy's map and the posterior its targets are drawn from and its
# moves scored under are agent i's (p, u), what its own sensing, its Φ refreshes and the merges it took part in gave
# it. With `team=1` it imagines itself alone; with `team=0` every teammate too, at its true position (positions are a
# few bytes to share; maps are not), each imagined to know what agent i knows (its belief is agent i's): every agent's
# belief is refreshed in Φ from the world's map, so a teammate kept with its own belief in a world whose map is agent
# i's would forget there what it sensed itself. It still reads which cells hold found targets (a small effect, as the
# probe's note says) and decides after the agents before it; a base rule's own memory (footprint-greedy's sightings,
# with `seen` or `age`) stays each teammate's, which B's teacher keeps none of. Everything else is the shipped
# planner's: the base rule, one sample, the expected finds, the horizon. The shipped planner with `controller.team=1`
# (alone, on the team's map) separates the map from the teammates. docs/lab/research.md ("Centralised, and what its
# gain needs") has the commands and the measurements; in short:
#
#     python -m searchrl.evaluate controller=rollout_own extensions=[analysis.rollout_own] +model=b \
#         controller.horizon=0 grid.world_sizes=[40,80,160] grid.n_targets=[8,16,32] grid.n_distributions=[16,32,64] \
#         grid.max_agents=[2,8,64] grid.repeats=1 grid.maps_per_cell=100 threads=1 cell=n40_N2 \
#         out_dir=runs/eval/roll100/rollout_own_h0
#     python analysis/rollout_table.py runs/eval/roll100/rollout_m1_h0 runs/eval/roll100/rollout_m1_h0_t1 \
#         runs/eval/roll100/rollout_own_h0 runs/eval/roll100/rollout_own_team_h0 \
#         --rules runs/eval/roll100/teacher_b runs/eval/roll100/coverage runs/eval/roll100/surfing \
#         --out analysis/out/rollout_own

# %%
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from searchrl.controllers.registry import register
from searchrl.controllers.rollout import Rollout, RolloutConfig, RuleFactory, choose
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams


# %%
@dataclass
class RolloutOwnConfig(RolloutConfig):
    name: str = "rollout_own"
    # 1: the deciding agent alone in its imagined worlds; 0: every teammate too (their positions known), each
    # imagined with the deciding agent's own belief (what it would take the teammates to know)
    team: int = 1


# %%
class OwnBeliefRollout(Rollout):
    """`Rollout` with each agent imagining itself alone on its own belief (module docstring)."""

    def __init__(self, config: WorldConfig, seed: int | WorldStreams = 0, *, rules: RuleFactory, **settings: Any):
        if settings.get("team", 1) not in (0, 1):
            raise ConfigError(
                f"controller.team={settings['team']!r} is not allowed: 1 (each agent imagined alone) or 0 (with "
                "every teammate, each on the agent's own belief)"
            )
        super().__init__(config, seed, rules=rules, **settings)

    def plan(self, state: WorldState, worlds: np.ndarray, base: np.ndarray, keys: np.ndarray) -> np.ndarray:
        chosen = base.copy()
        if worlds.size == 0:
            return chosen
        for agent in range(state.n_agents):
            own = known_to(state, agent)
            targets = self.imagine(own, worlds, keys)
            members = self.members(state, worlds, agent)  # (W, 1): the agent alone; or the whole team
            first = self.first(chosen, worlds, np.full(worlds.size, agent), members)
            scores = self.score(own, worlds, first, targets, [[int(keys[w])] for w in worlds], members)
            chosen[worlds, agent] = choose(scores, base[worlds, agent], 0.0)
        return chosen


# %%
# The per-agent arrays of what an agent knows, each teammate's replaced by the deciding agent's when imagined with it
KNOWLEDGE = ("belief", "belief_box", "belief_news", "belief_time", "belief_seen")


def known_to(state: WorldState, agent: int) -> WorldState:
    """The world as `agent` knows it (views of `state`'s arrays, no copies): its own (p, u) as the world's map, and
    its own belief as every agent's, so that each teammate's Φ refresh (from the map) and merges (of equal beliefs)
    agree with what it is imagined to know; `merged` false, as after beliefs edited by hand."""
    mine = {
        name: np.broadcast_to(getattr(state, name)[:, agent : agent + 1], getattr(state, name).shape)
        for name in KNOWLEDGE
    }
    belief = state.belief[:, agent]
    return replace(state, p=belief[:, 0], u=belief[:, 1], merged=np.zeros_like(state.merged), **mine)


# %% The controller joins the registry for this process only: `controller=rollout_own`
register("rollout_own", OwnBeliefRollout, RolloutOwnConfig, teacher=False)
