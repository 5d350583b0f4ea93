"""Evidence switch: target-greedy while the team finds what the prior promised where it swept, geometric coverage
once the finds fall behind.

A team that trusts a wrong prior keeps sweeping the prior's peaks, where no target is; coverage ignores the prior
and loses when it is right. The switch reads the evidence each step: where the team has swept, the prior expected
e = j · Σ_c t(c)·(1 − left(c)) / Σ_c t(c) detections, t = p·(1 − u/max u) the prior's density of targets
(§4.1.4's placement) and left(c) = Π (1 − Γ) over every footprint the team has put on c (what λk = 1 sensing leaves
of a cell). Once e ≥ MIN_EXPECTED (2) and (found + 1) / (e + 1) < `threshold`, the world's agents leave the prior
for good and sweep by geometric coverage (searchrl/controllers/coverage.py), each its own block.

What it reads: the team's found count and every agent's path, known to the whole team (in B they merge beliefs;
in C it is more than an agent knows), so it is a generous baseline for a decentralized learned policy. Its
knobs are tuned on seeds apart from the suites' (analysis/hedging.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.coverage import GeometricCoverage
from searchrl.controllers.greedy import FootprintGreedy
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.footprint import SUPPORT_DC, SUPPORT_DR, SUPPORT_G
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams


@njit(cache=True)
def sweep_footprints(pos, halo, left, dr, dc, g):
    """left (K, S, S) *= (1 − Γ) under the footprint of every agent at pos (K, N, 2) (unpadded; `halo` pads)."""
    for k in range(pos.shape[0]):
        for i in range(pos.shape[1]):
            r, c = pos[k, i, 0] + halo, pos[k, i, 1] + halo
            for s in range(dr.shape[0]):
                left[k, r + dr[s], c + dc[s]] *= 1.0 - g[s]


MIN_EXPECTED = 2.0  # the rule judges only once the prior expected this many detections where the team swept


@dataclass
class SwitchConfig(ControllerConfig):
    """Settings of `controller=switch` (EvidenceSwitch's keyword arguments)."""

    name: str = "switch"
    # Leave the prior once (found + 1) / (expected + 1) falls below this (0: never, the greedy alone).
    threshold: float = 0.5


class EvidenceSwitch:
    """Batched evidence switch (module docstring); per world, target-greedy (reach 2, the shipped policies' teacher)
    until the evidence turns, then coverage."""

    def __init__(
        self, config: WorldConfig, threshold: float = SwitchConfig.threshold, seed: int | WorldStreams = 0
    ) -> None:
        if not 0 <= threshold <= 1:
            raise ConfigError(f"threshold={threshold!r} is not allowed: 0 <= threshold <= 1 (0: never switch)")
        self.config, self.threshold = config, float(threshold)
        self.greedy = FootprintGreedy(config, horizon=3, w_p=0.0, w_u=0.0, w_t=1.0, reach=2.0, seed=seed)
        self.coverage = GeometricCoverage(config)
        self.left = np.ones((0, 0, 0))  # (K, S, S) float64: what the team's footprints left of each cell
        self.density = np.zeros((0, 0, 0))  # (K, S, S) float64: the prior's density of targets, summing to 1
        self.switched = np.zeros(0, bool)  # (K,): the world's agents sweep by coverage

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        if self.left.shape != state.p.shape:
            self.left, self.density = np.ones(state.p.shape), np.zeros(state.p.shape)
            self.switched, mask = np.zeros(state.n_worlds, bool), np.ones(state.n_worlds, bool)
        self.greedy.reset(state, mask)
        self.coverage.reset(state, mask)
        p, u, blocked = state.p[mask], state.u[mask], state.blocked[mask]
        u_max = u.max(axis=(1, 2), keepdims=True)
        density = np.where(blocked, 0.0, p * np.maximum(0.0, 1.0 - u / u_max))
        self.density[mask] = density / density.sum(axis=(1, 2), keepdims=True)
        self.left[mask], self.switched[mask] = 1.0, False

    def expected(self) -> np.ndarray:
        """(K,) the share of the prior's targets the team's footprints should have detected so far."""
        return (self.density * (1.0 - self.left)).sum(axis=(1, 2))

    def act(
        self, state: WorldState, maps: np.ndarray, vector: np.ndarray, active: np.ndarray | None = None
    ) -> np.ndarray:
        if self.left.shape != state.p.shape:
            self.reset(state, np.ones(state.n_worlds, bool))
        sweep_footprints(state.pos, state.halo, self.left, SUPPORT_DR, SUPPORT_DC, SUPPORT_G)
        expected = state.n_targets * self.expected()
        behind = (state.n_found + 1.0) / (expected + 1.0) < self.threshold
        self.switched |= (expected >= MIN_EXPECTED) & behind
        actions = self.greedy.act(state, maps, vector, active)
        if self.switched.any():  # coverage keeps its own plan; its actions are cheap next to greedy's
            actions = np.where(self.switched[:, None], self.coverage.act(state, maps, vector, active), actions)
        return actions
