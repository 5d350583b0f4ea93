# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Guidance: path_greedy's view of every move, in the policy's observation (an experiment)
#
# `path_greedy` beats every shipped policy among walls because it reads the whole world: it walks shortest paths
# (BFS over the walls its prior shows) to the best cells within `radius` moves, and when that pocket is cleared,
# to the nearest worthwhile cell anywhere. The policy sees an 11×11 window. This module registers, through
# searchrl's extension points, observation parts computed from what an agent holds (its belief, the walls, its
# position) with the rule's own machinery (searchrl/controllers/walls.py), the networks that read them, and the
# teachers of the experiments:
# - part `guidance`, 2·(A − 1) per agent: per move a, the best value, along a shortest path whose first move is a,
#   of target-greedy's footprint information within `radius` moves, discounted per move, divided by the best
#   move's (0 where nothing is in reach); and per move a, 1 where the pocket in reach holds less than the rule's
#   floor and a is the first move of the shortest path to the nearest worthwhile cell of the whole world (the walk
#   path_greedy would take), else 0.
# - part `evidence`, 2 per agent: its world's evidence switch statistics (searchrl/controllers/switch.py): the
#   team's finds against what the prior expected where it swept, (found + 1) / (expected + 1) over 2, and the
#   expected detections over MIN_EXPECTED, each clipped to [0, 1] (research/guided_b_evidence).
# - part `coverage_plan`, A − 1 per agent, one-hot: the move coverage's team plan gives the agent (the lane the
#   switch would walk once it has turned, which an 11×11 window cannot show; all 0 where it stays):
#   research/guided_b_plan.
# - networks `guided_cnn` (guidance), `guided_evidence_cnn` (+ evidence), `guided_plan_cnn` (+ coverage_plan): the
#   paper's network with each part added to the vector layer's input through its own gate that starts at 0, so a
#   policy started from one that lacks the part (`init=`) acts exactly as it at first.
# - teachers `walls_or_target`, `walls_or_switch`, `walls_or_oracle` (a privileged one: analysis/oracle_teacher.py's
#   OracleSwitch in open worlds, learning by cheating: research/guided_b_oracle).
#
# Each part remembers its episode (the rule's sightings, the switch's sweep, the coverage plan) and forgets it
# where a world starts one: the env and every policy controller hold their own copy. The research recipes name
# this module in their `extensions`, so the apps need nothing more:
#
#     python -m searchrl.train +experiment=research/guided_walls_b threads=1      # then guided_walls_b_ppo
#     python -m searchrl.evaluate extensions=[analysis.guided_b] suite=obstacles \
#         checkpoint=runs/train/guided/walls_b/model.zip out_dir=runs/suite/obstacles/policy/guided/walls_b

# %%
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
from gymnasium import spaces
from numba import njit, prange
from torch import nn

from analysis.oracle_teacher import OracleSwitch
from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.coverage import GeometricCoverage
from searchrl.controllers.greedy_kernels import cell_information, view_scratch
from searchrl.controllers.registry import make_controller, register
from searchrl.controllers.switch import MIN_EXPECTED, EvidenceSwitch, sweep_footprints
from searchrl.controllers.walls import PathGreedy, bfs, pocket_values
from searchrl.envs.parts import register_part
from searchrl.policies.extractor import SearchCNN
from searchrl.policies.networks import register_network
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import SUPPORT_DC, SUPPORT_DR, SUPPORT_G
from searchrl.world.parallel import chunk_count, chunk_span, world_threads
from searchrl.world.state import WorldState


# %%
@njit(parallel=True)  # not cached: a script's functions have no module to key a cache on
def guidance_values(w, params, memory, radius, floor, out, threads):
    """out (K, N, 2·(A − 1)) float32 <- the guidance of every agent (module text); agents shared among threads."""
    n_slots, side = out.shape[0] * out.shape[1], w.blocked.shape[1]
    n_chunks = chunk_count(n_slots, n_slots, threads)
    for chunk in prange(n_chunks):
        start, stop = chunk_span(chunk, n_chunks, 0, n_slots)
        _guidance_span(w, params, memory, radius, floor, out, start, stop, side)


@njit
def _guidance_span(w, params, memory, radius, floor, out, start, stop, side):
    dist, first = np.full((side, side), -1, np.int32), np.zeros((side, side), np.int64)
    queue = np.zeros((side * side, 2), np.int64)
    pos, h, n_actions = w.pos, w.halo, params.n_actions
    others = np.empty((1, 2), np.int64)
    best = np.zeros(n_actions)
    values = view_scratch(params)
    for slot in range(start, stop):
        k, i = slot // pos.shape[1], slot % pos.shape[1]
        r0, c0 = pos[k, i, 0] + h, pos[k, i, 1] + h
        pocket_values(w, params, memory, k, i, r0, c0, radius, dist, first, queue, best, others, values)
        top = best[1:].max()
        out[k, i, :] = 0.0
        for a in range(1, n_actions):
            out[k, i, a - 1] = best[a] / top if top > 0.0 else 0.0
        if top <= floor[k] * 13.0:  # the pocket is cleared: the first move towards the nearest worthwhile cell
            reached = bfs(w.blocked, k, r0, c0, np.int64(-1), n_actions, dist, first, queue)
            rate = memory.rates[k] if memory.known.shape[2] > 0 else 0.0
            for q in range(1, reached):
                r, c = queue[q, 0], queue[q, 1]
                info = cell_information(
                    params,
                    w.belief,
                    w.p,
                    memory.flat,
                    w.obs_scale[k, 0],
                    w.obs_scale[k, 1],
                    memory.seen,
                    memory.known,
                    rate,
                    w.t[k],
                    k,
                    i,
                    r,
                    c,
                )
                if info > floor[k]:
                    out[k, i, n_actions - 1 + first[r, c] - 1] = 1.0
                    break
            for q in range(reached):
                dist[queue[q, 0], queue[q, 1]] = -1


# %%
def _mask(state: WorldState, worlds: np.ndarray) -> np.ndarray:
    mask = np.zeros(state.n_worlds, bool)
    mask[worlds] = True
    return mask


class _RulePart:
    """A part computed by a rule with memory (`_make(config)`), built for the world config it is first filled for."""

    privileged: ClassVar[bool] = False
    high: ClassVar[float] = 1.0

    def __init__(self) -> None:
        self.config: WorldConfig | None = None
        self.rule = None

    def _for(self, state: WorldState, config: WorldConfig):
        if self.config != config:
            self.config, self.rule = config, self._make(config)
            self.rule.reset(state, np.ones(state.n_worlds, bool))
        return self.rule

    def reset(self, state: WorldState, config: WorldConfig, worlds: np.ndarray) -> None:
        self._for(state, config).reset(state, _mask(state, worlds))


@register_part
class Guidance(_RulePart):
    """`guidance` (module text): (N, 2·(A − 1)) per world, from path_greedy's memory of the episode."""

    key = "guidance"

    def _make(self, config: WorldConfig) -> PathGreedy:
        return PathGreedy(config)

    def shape(self, config: WorldConfig) -> tuple[int, ...]:
        return (config.n_agents, 2 * (config.n_actions - 1))

    def fill(self, state: WorldState, config: WorldConfig, out: np.ndarray, worlds: np.ndarray) -> None:
        rule = self._for(state, config)
        values = np.zeros(out.shape, np.float32)
        guidance_values(
            state.arrays(), rule._params, rule.remember(state), rule.radius, rule._floor, values, world_threads()
        )
        out[worlds] = values[worlds]


@register_part
class Evidence(_RulePart):
    """`evidence` (module text): (N, 2) per world, from the switch's sweep of the episode (every agent the same)."""

    key = "evidence"

    def _make(self, config: WorldConfig) -> EvidenceSwitch:
        return EvidenceSwitch(config)

    def shape(self, config: WorldConfig) -> tuple[int, ...]:
        return (config.n_agents, 2)

    def fill(self, state: WorldState, config: WorldConfig, out: np.ndarray, worlds: np.ndarray) -> None:
        tracker = self._for(state, config)
        if tracker.left.shape != state.p.shape:
            tracker.reset(state, np.ones(state.n_worlds, bool))
        sweep_footprints(state.pos, state.halo, tracker.left, SUPPORT_DR, SUPPORT_DC, SUPPORT_G)  # marks: idempotent
        expected = state.n_targets * tracker.expected()
        out[worlds, :, 0] = np.clip((state.n_found + 1.0) / (expected + 1.0) / 2.0, 0.0, 1.0)[worlds, None]
        out[worlds, :, 1] = np.clip(expected / MIN_EXPECTED, 0.0, 1.0)[worlds, None]


@register_part
class CoveragePlan(_RulePart):
    """`coverage_plan` (module text): (N, A − 1) per world, one-hot, coverage's move for each agent."""

    key = "coverage_plan"

    def _make(self, config: WorldConfig) -> GeometricCoverage:
        return GeometricCoverage(config)

    def shape(self, config: WorldConfig) -> tuple[int, ...]:
        return (config.n_agents, config.n_actions - 1)

    def fill(self, state: WorldState, config: WorldConfig, out: np.ndarray, worlds: np.ndarray) -> None:
        plan = self._for(state, config)
        if plan.waypoints.shape[:2] != (state.n_worlds, state.n_agents):
            plan.reset(state, np.ones(state.n_worlds, bool))
        move = plan.act(state, None, None)  # advances a waypoint once reached: a second call at once is the same
        out[worlds] = (move[:, :, None] == np.arange(1, config.n_actions))[worlds]


class VectorParts(SearchCNN):
    """The paper's network with parts of one vector per agent (`parts`) added to its vector layer's input, each
    through its own linear map and a gate that starts at 0 (a zero-initialised layer would not stay zero: SB3's
    orthogonal initialisation rewrites every linear layer). Weights copied from a network without a part act as
    that network until training opens the part's gate."""

    def __init__(
        self, observation_space: spaces.Dict, conv_channels=(32, 64, 128), vector_size: int = 32, fc_sizes=(256, 256)
    ) -> None:
        super().__init__(observation_space, conv_channels, vector_size, fc_sizes)
        missing = [key for key in self.parts if key not in observation_space.spaces]
        if missing:
            raise ValueError(f"the {type(self).__name__} network reads {missing[0]!r}, which the env does not observe")
        self.extra = nn.ModuleDict(
            {key: nn.Linear(observation_space[key].shape[0], vector_size, bias=False) for key in self.parts}
        )
        self.gates = nn.ParameterDict({key: nn.Parameter(torch.zeros(())) for key in self.parts})

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        """observations: {"map": (B, C, F, F), "vector": (B, 3), each part: (B, width)} -> (B, features_dim)."""
        maps = observations["map"].contiguous(memory_format=torch.channels_last)
        linear, relu = self.vector
        vector = linear(observations["vector"])
        for key in self.parts:
            vector = vector + self.gates[key] * self.extra[key](observations[key])
        return self.head(torch.cat([self.conv(maps), relu(vector)], dim=1))


@register_network("guided_cnn")
class GuidedCNN(VectorParts):
    parts = ("guidance",)


@register_network("guided_evidence_cnn")
class GuidedEvidenceCNN(VectorParts):
    parts = ("guidance", "evidence")


@register_network("guided_plan_cnn")
class GuidedPlanCNN(VectorParts):
    parts = ("guidance", "evidence", "coverage_plan")


# %%
@dataclass
class WallsOrTargetConfig(ControllerConfig):
    name: str = "walls_or_target"


class WallsOrTarget:
    """A teacher chosen per world from what every agent holds (the walls its prior shows): path_greedy in a world
    with obstacles, B's teacher (target-greedy, reach 2) in an open one: the best rule of each family."""

    def __init__(self, config: WorldConfig, seed=0) -> None:
        self.walls = make_controller("path_greedy", config, seed=seed)
        self.open = make_controller("greedy_target", config, seed=seed, settings={"reach": 2})

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        self.walls.reset(state, mask)
        self.open.reset(state, mask)

    def act(self, state, maps, vector, active=None) -> np.ndarray:
        h = state.halo
        walled = np.array([state.blocked[k, h : h + n, h : h + n].any() for k, n in enumerate(state.size)])
        return np.where(
            walled[:, None], self.walls.act(state, maps, vector, active), self.open.act(state, maps, vector, active)
        )


class WallsOrSwitch(WallsOrTarget):
    """As WallsOrTarget, the evidence switch (threshold 0.25, tuned apart from the suites) in open worlds: B's teacher
    until the team finds under a quarter of what the prior expected where it swept, then coverage."""

    def __init__(self, config: WorldConfig, seed=0) -> None:
        self.walls = make_controller("path_greedy", config, seed=seed)
        self.open = make_controller("switch", config, seed=seed, settings={"threshold": 0.25})


@dataclass
class WallsOrSwitchConfig(ControllerConfig):
    name: str = "walls_or_switch"


class WallsOrOracle(WallsOrTarget):
    """As WallsOrTarget, a privileged teacher in open worlds (analysis/oracle_teacher.py's OracleSwitch, learning by
    cheating): B's teacher where the prior ranks the true targets above 0.25, coverage from the first step where it
    does not. The student sees only its evidence and coverage's move: it learns when its evidence says to turn."""

    def __init__(self, config: WorldConfig, seed=0) -> None:
        self.walls = make_controller("path_greedy", config, seed=seed)
        self.open = OracleSwitch(config, threshold=0.25, seed=seed)


@dataclass
class WallsOrOracleConfig(ControllerConfig):
    name: str = "walls_or_oracle"


register("walls_or_target", WallsOrTarget, WallsOrTargetConfig)  # a teacher: imitation.teacher=walls_or_target
register("walls_or_switch", WallsOrSwitch, WallsOrSwitchConfig)
register("walls_or_oracle", WallsOrOracle, WallsOrOracleConfig)
