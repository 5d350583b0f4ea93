"""Coarse views of a whole world: an agent's belief map, or the world's true state, pooled onto a G×G grid.

The paper's agents see an 11×11 window and a 3-vector (searchrl/world/observe.py). These views cover the whole
n×n map at any n: cell (row, col) of a world of side n falls in coarse cell (row·G // n, col·G // n), and a coarse
cell holds the mean of its cells (a count, for targets and agents). Two views, each (K, N, C, G, G) float32:

- `own_map` (what an agent knows; an actor may read it): the agent's belief p and u scaled as in the window
  (1 / the prior's peak), and a one-hot of its own coarse cell. C = OWN_MAP_CHANNELS = 3.
- `true_state` (what no agent knows; only a critic during training may read it): the team's merged belief (the
  elementwise min of every agent's p and u, scaled), the targets not yet found (count per coarse cell), every
  agent (count per coarse cell / N), the agent's own coarse cell, and the time left (1 − t / max_steps, the same in
  every cell). C = TRUE_STATE_CHANNELS = 6.

Sums run in a fixed order in compiled code without fastmath, so the views are the same bits on every CPU.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import ClassVar, Protocol

import numpy as np
from numba import njit

from searchrl.world.config import WorldConfig
from searchrl.world.kernels import CACHE
from searchrl.world.state import WorldState

OWN_MAP_CHANNELS = 3
TRUE_STATE_CHANNELS = 6


def own_map(state: WorldState, grid: int, out: np.ndarray, worlds: np.ndarray) -> np.ndarray:
    """Fill out[k] (N, OWN_MAP_CHANNELS, grid, grid) for each world k of `worlds` (int64) and return `out`."""
    _own_map(state.arrays(), np.int64(grid), out, np.asarray(worlds, np.int64))
    return out


def true_state(state: WorldState, grid: int, max_steps: int, out: np.ndarray, worlds: np.ndarray) -> np.ndarray:
    """Fill out[k] (N, TRUE_STATE_CHANNELS, grid, grid) for each world k of `worlds` (int64) and return `out`."""
    _true_state(state.arrays(), np.int64(grid), np.int64(max_steps), out, np.asarray(worlds, np.int64))
    return out


@njit(cache=CACHE)
def _coarse_index(n, grid):
    """((n,) the coarse row (or column) of each of a side's n cells, (grid,) how many cells each coarse row holds),
    int64: no division in the inner loops."""
    index, counts = np.empty(n, np.int64), np.zeros(grid, np.int64)
    for r in range(n):
        index[r] = r * grid // n
        counts[index[r]] += 1
    return index, counts


@njit(cache=CACHE)
def _pool(maps, h, n, index, counts, scale, acc, dst):
    """dst (2, grid, grid) = the mean of maps (2, ·, ·)'s n × n cells from (h, h) over each coarse cell (index,
    counts: `_coarse_index`), times scale (2,); acc (2, grid, grid) float64 is work space."""
    acc[:] = 0.0
    for r in range(n):
        gr = index[r]
        for c in range(n):
            gc = index[c]
            acc[0, gr, gc] += maps[0, r + h, c + h]
            acc[1, gr, gc] += maps[1, r + h, c + h]
    for gr in range(acc.shape[1]):
        for gc in range(acc.shape[2]):
            cells = counts[gr] * counts[gc]
            dst[0, gr, gc] = acc[0, gr, gc] / cells * scale[0] if cells else 0.0
            dst[1, gr, gc] = acc[1, gr, gc] / cells * scale[1] if cells else 0.0


@njit(cache=CACHE)
def _own_map(w, grid, out, worlds):
    h, belief, pos, size, scale = w.halo, w.belief, w.pos, w.size, w.obs_scale  # each field read once (kernels.py)
    acc = np.zeros((2, grid, grid), np.float64)
    for k in worlds:
        n = size[k]
        index, counts = _coarse_index(n, grid)
        for i in range(pos.shape[1]):
            _pool(belief[k, i], h, n, index, counts, scale[k], acc, out[k, i])
            out[k, i, 2] = 0.0
            out[k, i, 2, pos[k, i, 0] * grid // n, pos[k, i, 1] * grid // n] = 1.0


@njit(cache=CACHE)
def _true_state(w, grid, max_steps, out, worlds):
    h, belief, pos, size, scale = w.halo, w.belief, w.pos, w.size, w.obs_scale  # each field read once (kernels.py)
    n_agents = pos.shape[1]
    shared, acc = np.zeros((5, grid, grid), np.float64), np.zeros((2, grid, grid), np.float64)
    for k in worlds:
        n = size[k]
        index, counts = _coarse_index(n, grid)
        shared[:] = 0.0
        team = belief[k, 0, :, h : h + n, h : h + n].copy()  # (2, n, n): the min over agents, agent by agent
        for i in range(1, n_agents):  # agent-major: each agent's map read in memory order
            for layer in range(2):
                for r in range(n):
                    for c in range(n):
                        team[layer, r, c] = min(team[layer, r, c], belief[k, i, layer, r + h, c + h])
        _pool(team, np.int64(0), n, index, counts, scale[k], acc, shared)
        for j in range(w.target_pos.shape[1]):
            if w.target_valid[k, j] and not w.target_found[k, j]:
                shared[2, w.target_pos[k, j, 0] * grid // n, w.target_pos[k, j, 1] * grid // n] += 1.0
        for i in range(n_agents):
            shared[3, pos[k, i, 0] * grid // n, pos[k, i, 1] * grid // n] += 1.0 / n_agents
        left = max(0.0, 1.0 - w.t[k] / max_steps)
        for i in range(n_agents):
            for gr in range(grid):
                for gc in range(grid):
                    for ch in range(4):
                        out[k, i, ch, gr, gc] = shared[ch, gr, gc]
                    out[k, i, 4, gr, gc] = 0.0
                    out[k, i, 5, gr, gc] = left
            out[k, i, 4, pos[k, i, 0] * grid // n, pos[k, i, 1] * grid // n] = 1.0


class ObservationPart(Protocol):
    """An observation beside the window and the 3-vector, injected into `SearchWorld(parts=...)`: under `key`, an
    array of `shape(config)` ((N, ...)) per world, in [0, high], filled for the worlds listed after every reset and
    step. A part that remembers its episode (a rule's memory, a tracker) also has `reset(state, config, worlds)`,
    called for the listed worlds when they start an episode, before they are filled; every world holds its own
    copy of each part. A copy built for a critic with other settings than the actor's holds its own `key`
    (searchrl/policies/networks.py `critic_keys`)."""

    key: str  # the class's name for it
    privileged: ClassVar[bool]  # the true state: for a critic during training, never for an actor
    high: ClassVar[float]

    def shape(self, config: WorldConfig) -> tuple[int, ...]: ...

    def fill(self, state: WorldState, config: WorldConfig, out: np.ndarray, worlds: np.ndarray) -> None: ...


def reset_parts(parts: Iterable[ObservationPart], state: WorldState, config: WorldConfig, worlds: np.ndarray) -> None:
    """Call `reset` of each part that has one (it remembers its episode) for the listed worlds (int64)."""
    for part in parts:
        reset = getattr(part, "reset", None)
        if reset is not None:
            reset(state, config, worlds)


class CoarseView:
    """A part that is a coarse view of the whole world: (N, channels, grid, grid) per world."""

    channels: ClassVar[int]

    def __init__(self, grid: int = 16) -> None:
        self.grid = grid

    def shape(self, config: WorldConfig) -> tuple[int, ...]:
        return (config.n_agents, self.channels, self.grid, self.grid)


class OwnMap(CoarseView):
    """The observation part `own_map` (module docstring): an agent's own belief map, coarse; an actor may read it."""

    key, privileged, high, channels = "own_map", False, 1.0, OWN_MAP_CHANNELS

    def fill(self, state: WorldState, config: WorldConfig, out: np.ndarray, worlds: np.ndarray) -> None:
        own_map(state, self.grid, out, worlds)


class TrueState(CoarseView):
    """The observation part `true_state` (module docstring): the world's true state, coarse; a critic's only."""

    key, privileged, high, channels = "true_state", True, float("inf"), TRUE_STATE_CHANNELS  # high: target counts

    def fill(self, state: WorldState, config: WorldConfig, out: np.ndarray, worlds: np.ndarray) -> None:
        true_state(state, self.grid, config.max_steps, out, worlds)
