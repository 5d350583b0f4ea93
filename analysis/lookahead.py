# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Rollout over the teacher: one step of policy improvement on the team's posterior (an experiment)
#
# `controller=lookahead`: at every step, for every agent, each of its moves is tried in `samples` imagined copies of
# the world, everyone playing target-greedy (reach 2, B's teacher) after it for `horizon` steps (0: to the episode's
# end). The agent plays the teacher's move unless another finds more targets on average by more than `confidence`
# standard errors of the paired difference over the samples (at 0, any higher mean: noise then moves the agent
# back and forth). Bertsekas' rollout; all agents choose at once, each assuming the others play the teacher. An
# imagined copy is the world as the team knows it: its agents where they stand, the probability map after every
# sensing so far (with lam·k = 1 that is the posterior given no detection), and the unfound targets redrawn from it
# as a reset draws them (§4.1.4). Centralised: it reads the whole team's knowledge and positions, never the true
# targets. Copies of one sample draw the same numbers whatever the move (common random numbers).
#
#     python -m searchrl.evaluate controller=lookahead extensions=[analysis.lookahead] +model=b \
#         grid.world_sizes=[40] grid.n_targets=[8] grid.n_distributions=[16] grid.max_agents=[2] threads=1
#
# It costs moves × samples × agents imagined worlds per agent-step: a probe of what planning on the team's
# posterior adds to the teacher, and a candidate teacher for expert iteration, not a controller to deploy.

# %%
from dataclasses import dataclass, fields

import numpy as np

from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.posterior import posterior_targets, remember_prior_u
from searchrl.controllers.registry import make_controller, register
from searchrl.controllers.rollout import choose  # the teacher's move unless another is surely better
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams, random_source


# %%
@dataclass
class LookaheadConfig(ControllerConfig):
    name: str = "lookahead"
    samples: int = 8  # imagined worlds per move
    horizon: int = 0  # imagined steps after the move (0: to the episode's end)
    reach: float = 2.0  # the teacher's (target-greedy's) reach
    confidence: float = 2.0  # leave the teacher's move only for one better by this many standard errors (0: any)


def copy_world(source: WorldState, k: int, target: SearchWorld) -> None:
    """Every world of `target` becomes world k of `source` (the same config, so the same padded side)."""
    for field in fields(WorldState):
        value = getattr(source, field.name)
        if isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == source.n_worlds:
            getattr(target.state, field.name)[:] = value[k]
    target.started = True


class Lookahead:
    """One step of rollout over target-greedy for every agent, planned on the team's posterior."""

    def __init__(
        self,
        config: WorldConfig,
        samples: int = 8,
        horizon: int = 0,
        reach: float = 2.0,
        confidence: float = 2.0,
        seed: int | WorldStreams = 0,
    ) -> None:
        if samples < 1 or horizon < 0 or confidence < 0:
            raise ValueError(
                f"samples={samples}, horizon={horizon}, confidence={confidence} are not allowed: samples >= 1, "
                "horizon >= 0, confidence >= 0"
            )
        self.config, self.samples, self.horizon, self.reach = config, int(samples), int(horizon), float(reach)
        self.confidence = float(confidence)
        self.teacher = make_controller("greedy_target", config, seed=seed, settings={"reach": reach})
        self.rng = random_source(seed)  # one key per world and step for its plan: the episode's own stream
        self.prior_u = np.zeros((0, 0, 0))

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        self.teacher.reset(state, mask)
        self.prior_u = remember_prior_u(self.prior_u, state, mask)

    def act(self, state: WorldState, maps, vector, active: np.ndarray | None = None) -> np.ndarray:
        if self.prior_u.shape != state.u.shape:
            self.reset(state, np.ones(state.n_worlds, bool))
        base = self.teacher.act(state, maps, vector)
        keys = self.rng.integers(0, 2**31, size=(state.n_worlds, 1))
        out = base.copy()
        for k in range(state.n_worlds):
            if (active is None or active[k]) and state.n_found[k] < state.n_targets[k]:
                out[k] = self.plan(state, k, base[k], int(keys[k, 0]))
        return out

    def plan(self, state: WorldState, k: int, base: np.ndarray, key: int) -> np.ndarray:
        """(N,) the move of each agent of world k: world ((i·A + a)·L + l) is agent i playing a in sample l."""
        n_agents, n_actions, n_samples = state.n_agents, self.config.n_actions, self.samples
        count = n_agents * n_actions * n_samples
        sample = np.tile(np.arange(n_samples), n_agents * n_actions)
        world = SearchWorld(self.config, count, auto_reset=False, observe=False)
        copy_world(state, k, world)
        self.imagine_targets(world, state, k, np.random.default_rng([key, 0]))
        world.rng = WorldStreams([[key, 1, int(s)] for s in sample])
        teacher = make_controller(
            "greedy_target",
            self.config,
            seed=WorldStreams([[key, 2, int(s)] for s in sample]),
            settings={"reach": self.reach},
        )
        teacher.reset(world.state, np.ones(count, bool))
        actions = np.tile(base, (count, 1))
        agent, move = (
            np.repeat(np.arange(n_agents), n_actions * n_samples),
            np.tile(np.repeat(np.arange(n_actions), n_samples), n_agents),
        )
        actions[np.arange(count), agent] = move
        world.step(actions)
        end = self.config.max_steps if self.horizon == 0 else int(state.t[k]) + 1 + self.horizon
        while (
            int(world.state.t[0]) < min(end, self.config.max_steps)
            and (world.state.n_found < world.state.n_targets).any()
        ):
            world.step(teacher.act(world.state, None, None))
        return choose(world.state.n_found.reshape(n_agents, n_actions, n_samples), base, self.confidence)

    def imagine_targets(self, world: SearchWorld, state: WorldState, k: int, rng: np.random.Generator) -> None:
        """Sample l's unfound targets, one draw per sample shared by every move, from the team's posterior."""
        h, n = state.halo, int(state.size[k])
        inner = (k, slice(h, h + n), slice(h, h + n))
        lost = np.flatnonzero(state.target_valid[k] & ~state.target_found[k])
        free = ~state.blocked[inner] & ~state.found_grid[inner]
        draws = posterior_targets(state.p[inner], self.prior_u[inner], free, len(lost), self.samples, rng)
        for w in range(world.n_worlds):
            world.state.target_pos[w, lost] = draws[w % self.samples]


# %% The controller joins the registry for this process only: `controller=lookahead`
register("lookahead", Lookahead, LookaheadConfig)
