"""A decentralised rollout planner (an experiment, outside the library): how much of `controller=rollout`'s gain
over B's teacher survives when each agent plans on what it knows alone.

The shipped planner is centralised: agent i's moves are played out in imagined copies of the whole world (every
teammate's position, belief and rule) and scored under the team's posterior, the map of everything any agent has
sensed. Here agent i imagines itself alone (`team=1`: no teammate in its copies) on its own belief: the copy's map
and the posterior its targets are drawn from and its moves scored under are agent i's (p, u), what its own sensing
and the merges it took part in gave it. It still reads which cells hold found targets (a small effect, as the
probe's note says) and decides after the agents before it (whose choices it no longer imagines). Everything else is
the shipped planner's: the base rule, one sample, the expected finds, the horizon. The agent alone, because every
agent's belief is refreshed in Φ from the world's map: a teammate imagined in a world whose map is another agent's
belief would forget there what it sensed itself (tried: 0.206 below the teacher at 40 x 2, the teammates searching
again what they had searched). The shipped planner with `controller.team=1` (alone, on the team's map) separates
the two: the map, and the teammates.

    python -m searchrl.evaluate controller=rollout_own extensions=[analysis.rollout_own] +model=b \
        controller.horizon=0 grid.world_sizes=[40,80,160] grid.n_targets=[8,16,32] grid.n_distributions=[16,32,64] \
        grid.max_agents=[2,8,64] grid.repeats=1 grid.maps_per_cell=100 threads=1 cell=n40_N2 \
        out_dir=runs/eval/roll100/rollout_own_h0
    python analysis/rollout_table.py runs/eval/roll100/rollout_m1_h0 runs/eval/roll100/rollout_own_h0 \
        --rules runs/eval/roll100/teacher_b runs/eval/roll100/coverage runs/eval/roll100/surfing \
        --out analysis/out/rollout_own
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from searchrl.controllers.registry import register
from searchrl.controllers.rollout import Rollout, RolloutConfig, RuleFactory, choose
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams


@dataclass
class RolloutOwnConfig(RolloutConfig):
    name: str = "rollout_own"
    team: int = 1  # the deciding agent alone in its imagined worlds (the only value: module docstring)


class OwnBeliefRollout(Rollout):
    """`Rollout` with each agent imagining itself alone on its own belief (module docstring)."""

    def __init__(self, config: WorldConfig, seed: int | WorldStreams = 0, *, rules: RuleFactory, **settings: Any):
        if settings.get("team", 1) != 1:
            raise ConfigError(f"controller.team={settings['team']!r} is not allowed: 1 (each agent imagined alone)")
        super().__init__(config, seed, rules=rules, **settings)

    def plan(self, state: WorldState, worlds: np.ndarray, base: np.ndarray, keys: np.ndarray) -> np.ndarray:
        chosen = base.copy()
        if worlds.size == 0:
            return chosen
        for agent in range(state.n_agents):
            # The world as agent i knows it: its own (p, u) as the map (the same arrays, not copies)
            own = replace(state, p=state.belief[:, agent, 0], u=state.belief[:, agent, 1])
            targets = self.imagine(own, worlds, keys)
            members = self.members(state, worlds, agent)  # (W, 1): the agent alone
            first = self.first(chosen, worlds, np.full(worlds.size, agent), members)
            scores = self.score(own, worlds, first, targets, [[int(keys[w])] for w in worlds], members)
            chosen[worlds, agent] = choose(scores, base[worlds, agent], 0.0)
        return chosen


register("rollout_own", OwnBeliefRollout, RolloutOwnConfig, teacher=False)
