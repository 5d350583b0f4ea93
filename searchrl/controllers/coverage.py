"""Geometric coverage (§6.3's baseline): the domain is split into N near-square blocks, one per agent (by index),
and each agent sweeps its block in boustrophedon lanes, ignoring the prior.

Lanes run east-west from edge to edge of the block, `2·radius + 1` rows apart, so every cell passes within
`radius` rows of a lane (radius 1: each cell is seen with Γ ≥ 0.37 three steps in a row). An agent first walks to
the corner of its block nearest to its start, sweeps, then sweeps back in reverse, for as long as the episode
lasts. Moves follow the larger offset to the next waypoint (diagonal when allowed and useful); when that cell is
visibly occupied the agent tries the other axis, then keeps right (sidesteps to the right of its heading), so
two agents meeting head-on pass each other instead of waiting forever.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from searchrl.controllers.base import ControllerConfig
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.footprint import MOVES
from searchrl.world.state import WorldState


def partition(n: int, n_agents: int) -> list[tuple[int, int, int, int]]:
    """N blocks (r0, r1, c0, c1), half-open, tiling the n×n domain: ceil(√N) rows of blocks, the first
    N mod rows rows holding one block more."""
    rows = max(1, min(n, math.isqrt(n_agents - 1) + 1 if n_agents > 1 else 1))
    per_row = [n_agents // rows + (1 if r < n_agents % rows else 0) for r in range(rows)]
    edges = np.linspace(0, n, rows + 1).round().astype(int)
    blocks = []
    for r in range(rows):
        col_edges = np.linspace(0, n, per_row[r] + 1).round().astype(int)
        blocks += [(edges[r], edges[r + 1], col_edges[c], col_edges[c + 1]) for c in range(per_row[r])]
    return blocks


def sweep(block: tuple[int, int, int, int], start: tuple[int, int], radius: int) -> np.ndarray:
    """Waypoints (W, 2) of a boustrophedon sweep of `block`, beginning at the corner nearest to `start`."""
    r0, r1, c0, c1 = block
    spacing = 2 * radius + 1
    top, bottom = min(r0 + radius, r1 - 1), max(r1 - 1 - radius, r0)
    if top > bottom:  # a block thinner than two lanes' reach: one lane through its middle
        top = bottom = (r0 + r1 - 1) // 2
    lanes = list(range(top, bottom + 1, spacing))
    if lanes[-1] < bottom:  # the last rows are covered by one more lane
        lanes.append(bottom)
    left, right = c0, c1 - 1  # edge to edge: the footprint reaches no further sideways than along the lane
    if abs(start[0] - lanes[-1]) < abs(start[0] - lanes[0]):
        lanes.reverse()
    ends = (left, right) if abs(start[1] - left) <= abs(start[1] - right) else (right, left)
    points = []
    for j, lane in enumerate(lanes):
        a, b = ends if j % 2 == 0 else ends[::-1]
        points += [(lane, a), (lane, b)]
    return np.array(points, np.int64)


@njit(cache=True)
def coverage_actions(pos, occupant, blocked, h, waypoints, n_points, index, diagonal, out):
    """out (K,N) <- moves towards each agent's current waypoint; index (K,N) advances (and the plan reverses
    at its end) when a waypoint is reached."""
    n_worlds, n_agents = pos.shape[0], pos.shape[1]
    for k in range(n_worlds):
        for i in range(n_agents):
            m = n_points[k, i]
            r, c = pos[k, i, 0], pos[k, i, 1]
            if r == waypoints[k, i, index[k, i], 0] and c == waypoints[k, i, index[k, i], 1]:
                index[k, i] += 1
                if index[k, i] == m:  # sweep back in reverse
                    waypoints[k, i, :m] = waypoints[k, i, :m][::-1].copy()
                    index[k, i] = 1 if m > 1 else 0
            dr = waypoints[k, i, index[k, i], 0] - r
            dc = waypoints[k, i, index[k, i], 1] - c
            sr, sc = (dr > 0) - (dr < 0), (dc > 0) - (dc < 0)
            if diagonal and sr != 0 and sc != 0:
                options = ((sr, sc), (sr, 0), (0, sc), (0, 0))
            elif abs(dr) >= abs(dc):
                options = ((sr, 0), (0, sc), (0, -sr), (0, 0))  # keep right of a north/south heading
            else:
                options = ((0, sc), (sr, 0), (sc, 0), (0, 0))  # keep right of an east/west heading
            out[k, i] = 0
            for o in options:
                if o[0] == 0 and o[1] == 0:
                    continue
                tr, tc = r + o[0] + h, c + o[1] + h
                if not blocked[k, tr, tc] and occupant[k, tr, tc] < 0:
                    out[k, i] = _action_of(o[0], o[1])
                    break


@njit(cache=True)
def _action_of(dr, dc):
    # MOVES: 0 stay, 1 N, 2 E, 3 S, 4 W, 5 NE, 6 SE, 7 SW, 8 NW
    if dr == -1 and dc == 0:
        return 1
    if dr == 0 and dc == 1:
        return 2
    if dr == 1 and dc == 0:
        return 3
    if dr == 0 and dc == -1:
        return 4
    if dr == -1 and dc == 1:
        return 5
    if dr == 1 and dc == 1:
        return 6
    if dr == 1 and dc == -1:
        return 7
    if dr == -1 and dc == -1:
        return 8
    return 0


@dataclass
class CoverageConfig(ControllerConfig):
    """Settings of `controller=coverage` (GeometricCoverage's keyword arguments)."""

    name: str = "coverage"
    radius: int = 1  # lanes 2·radius + 1 rows apart


class GeometricCoverage:
    """Batched coverage controller; `radius` sets the lane spacing (2·radius + 1)."""

    def __init__(self, config: WorldConfig, radius: int = CoverageConfig.radius) -> None:  # CoverageConfig's default
        if radius < 0:
            raise ConfigError(f"radius={radius!r} is not allowed: must be >= 0")
        self.config, self.radius = config, radius
        self.waypoints = np.zeros((0, 0, 1, 2), np.int64)
        self.n_points = np.zeros((0, 0), np.int64)
        self.index = np.zeros((0, 0), np.int64)

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        """Plan the sweeps of the worlds in `mask` from their sizes and the agents' start cells."""
        k, n_agents = state.n_worlds, state.n_agents
        longest = 2 * (int(state.size.max()) // (2 * self.radius + 1) + 2)
        if self.waypoints.shape[:2] != (k, n_agents) or self.waypoints.shape[2] < longest:
            self.waypoints = np.zeros((k, n_agents, longest, 2), np.int64)
            self.n_points = np.ones((k, n_agents), np.int64)
            self.index = np.zeros((k, n_agents), np.int64)
            mask = np.ones(k, bool)
        for w in np.flatnonzero(mask):
            blocks = partition(int(state.size[w]), n_agents)
            for i, block in enumerate(blocks):
                plan = sweep(block, tuple(state.pos[w, i]), self.radius)
                self.waypoints[w, i, : len(plan)] = plan
                self.n_points[w, i] = len(plan)
                self.index[w, i] = 0

    def act(
        self, state: WorldState, maps: np.ndarray, vector: np.ndarray, active: np.ndarray | None = None
    ) -> np.ndarray:
        out = np.empty((state.n_worlds, state.n_agents), np.int64)
        coverage_actions(
            state.pos,
            state.occupant,
            state.blocked,
            state.halo,
            self.waypoints,
            self.n_points,
            self.index,
            self.config.diagonal,
            out,
        )
        return out


assert MOVES[1].tolist() == [-1, 0] and MOVES[6].tolist() == [1, 1]  # _action_of mirrors this table
