"""Heuristics that handle walls: moves scored along shortest paths (breadth-first search), not straight lines.

Footprint-greedy scores a move by what Γ would sense going straight on, so beside a wall every look-ahead runs into
it, and an agent whose view is cleared moves at random; geometric coverage plans lanes over a wall-free square.
Among walls both waste their steps. The two rules here see the walls the prior shows (p = 0 on every obstacle):

- `PathGreedy` (`controller=path_greedy`): each agent searches the free cells within `radius` moves
  (BFS over the moves of its model); a cell x reached in d moves is worth F(x) · discount^(d − 1), F(x) its
  footprint's information (greedy's I, the cells inside the field of view; searchrl/controllers/greedy.py); the
  agent takes the first move of the path to the best cell. When nothing in reach is worth `worth` × the prior's mean
  information per cell (its pocket is cleared), it walks the shortest path to the nearest cell of its belief that
  is, over the whole world.
- `SweepCoverage` (`controller=sweep`): the team's swept map (Π (1 − Γ) over every footprint, as in
  searchrl/controllers/switch.py); each agent walks the shortest path to the nearest cell less than half swept
  that no agent before it in the team claimed this step (a claim covers `spacing` cells around the target), so
  it sweeps around walls into every pocket and the team spreads out.

Both reach every free cell of a connected world eventually (tests/test_walls.py, on mazes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from searchrl.controllers.base import ControllerConfig, FallbackHeuristic
from searchrl.controllers.greedy import FootprintGreedy
from searchrl.controllers.greedy_kernels import cell_information, footprint_information, view_scratch, view_values
from searchrl.controllers.switch import sweep_footprints
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.footprint import MOVES, SUPPORT_DC, SUPPORT_DR, SUPPORT_G
from searchrl.world.parallel import chunk_count, chunk_span, world_threads
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams


@njit(cache=True)
def bfs(blocked, k, r0, c0, limit, n_actions, dist, first, queue):
    """Breadth-first search over the free cells of world k from padded cell (r0, c0), `limit` moves at most (< 0:
    no limit), with MOVES[1:n_actions]. dist (S, S) int32 must be -1 everywhere on entry; fills dist and first (the
    first move of a shortest path) on the cells reached, queue (S·S, 2) with them in order; returns their count
    (the caller resets dist on them)."""
    dist[r0, c0], first[r0, c0] = 0, 0
    queue[0, 0], queue[0, 1] = r0, c0
    head, tail = 0, 1
    while head < tail:
        r, c = queue[head, 0], queue[head, 1]
        head += 1
        if 0 <= limit <= dist[r, c]:
            continue
        for a in range(1, n_actions):
            rr, cc = r + MOVES[a, 0], c + MOVES[a, 1]
            if blocked[k, rr, cc] or dist[rr, cc] >= 0:
                continue
            dist[rr, cc] = dist[r, c] + 1
            first[rr, cc] = a if dist[r, c] == 0 else first[r, c]
            queue[tail, 0], queue[tail, 1] = rr, cc
            tail += 1
    return tail


@njit(cache=True)
def pocket_values(w, params, memory, k, i, r0, c0, radius, dist, first, queue, best, others, values):
    """best (A,) <- for each first move a, the best value of a cell within `radius` moves of agent i of world k at
    padded (r0, c0) whose shortest path starts with a: its footprint information (`footprint_information`)
    times discount^(moves − 1). dist, first, queue are `bfs`'s scratch, dist left all -1 again; others (1, 2)
    int64 scratch (no agent is contested here); values: `view_values`' scratch (`view_scratch`)."""
    reached = bfs(w.blocked, k, r0, c0, radius, params.n_actions, dist, first, queue)
    best[:] = 0.0
    view_values(w, params, memory, k, i, r0, c0, others, np.int64(0), values)
    for q in range(1, reached):
        r, c = queue[q, 0], queue[q, 1]
        value = footprint_information(params, values, r - r0, c - c0)
        value *= params.discount ** (dist[r, c] - 1)
        a = first[r, c]
        if value > best[a]:
            best[a] = value
    for q in range(reached):
        dist[queue[q, 0], queue[q, 1]] = -1


@njit(cache=True, parallel=True)
def path_greedy_actions(w, params, memory, radius, floor, fallback, out, threads):
    """out (K, N) <- PathGreedy's moves (module docstring); floor (K,): the information a cell must hold to be
    worth a walk. The K·N agents are shared among `threads` numba threads (`searchrl.world.parallel.world_threads()`),
    each chunk with its own BFS scratch, as in `greedy_actions`: an agent's move reads the state and writes its own
    entry of `out` only."""
    n_slots, side = out.shape[0] * out.shape[1], w.blocked.shape[1]
    n_chunks = chunk_count(n_slots, n_slots, threads)
    if n_chunks == 1:  # in this thread: waking a worker for the only chunk would just add its wake-up
        _path_greedy_span(w, params, memory, radius, floor, fallback, out, np.int64(0), n_slots, side)
        return
    for chunk in prange(n_chunks):
        start, stop = chunk_span(chunk, n_chunks, 0, n_slots)
        _path_greedy_span(w, params, memory, radius, floor, fallback, out, start, stop, side)


@njit(cache=True)
def _path_greedy_span(w, params, memory, radius, floor, fallback, out, start, stop, side):
    """`path_greedy_actions` for the agents start..stop-1 of the K·N, world-major, with scratch of its own: dist,
    first (S, S) and queue (S·S, 2) for `bfs`."""
    dist, first = np.full((side, side), -1, np.int32), np.zeros((side, side), np.int64)
    queue = np.zeros((side * side, 2), np.int64)
    pos, occupant, h, n_actions = w.pos, w.occupant, w.halo, params.n_actions
    sp_all, su_all, rate_all, now_all = w.obs_scale, w.obs_scale, memory.rates, w.t
    others = np.empty((1, 2), np.int64)
    best = np.zeros(n_actions)  # the best value of a cell each first move leads to
    values = view_scratch(params)
    for slot in range(start, stop):
        k, i = slot // pos.shape[1], slot % pos.shape[1]
        r0, c0 = pos[k, i, 0] + h, pos[k, i, 1] + h
        pocket_values(w, params, memory, k, i, r0, c0, radius, dist, first, queue, best, others, values)
        choice, score = 0, floor[k] * 13.0  # a footprint's worth: 13 cells at the floor
        for a in range(1, n_actions):
            if best[a] > score and occupant[k, r0 + MOVES[a, 0], c0 + MOVES[a, 1]] < 0:
                choice, score = a, best[a]
        if choice == 0:  # the pocket in reach is cleared: the nearest worthwhile cell, over the whole world
            reached = bfs(w.blocked, k, r0, c0, np.int64(-1), n_actions, dist, first, queue)
            sp, su = sp_all[k, 0], su_all[k, 1]
            rate = rate_all[k] if memory.known.shape[2] > 0 else 0.0
            for q in range(1, reached):
                r, c = queue[q, 0], queue[q, 1]
                info = cell_information(
                    params, w.belief, w.p, memory.flat, sp, su, memory.seen, memory.known, rate, now_all[k], k, i, r, c
                )
                if info > floor[k]:
                    a = first[r, c]
                    if occupant[k, r0 + MOVES[a, 0], c0 + MOVES[a, 1]] < 0:
                        choice = a
                    break
            for q in range(reached):
                dist[queue[q, 0], queue[q, 1]] = -1
        out[k, i] = choice if choice > 0 else fallback[k, i]


@dataclass
class PathGreedyConfig(ControllerConfig):
    """Settings of `controller=path_greedy`: cells scored along shortest paths within `radius` moves by target-greedy's
    information (reach 2, the shipped policies' teacher; searchrl/controllers/greedy.py), each move further weighted
    by `discount`, and a walk to the nearest cell worth `worth` × the prior's mean."""

    name: str = "path_greedy"
    radius: int = 5  # moves searched each step: half the field of view, what the agent sees
    discount: float = 0.7
    worth: float = 0.05


class PathGreedy(FootprintGreedy):
    """Batched PathGreedy (module docstring); its information is target-greedy's (w_t = 1, reach 2)."""

    def __init__(
        self,
        config: WorldConfig,
        radius: int = PathGreedyConfig.radius,
        discount: float = PathGreedyConfig.discount,
        worth: float = PathGreedyConfig.worth,
        seed: int | WorldStreams = 0,
    ) -> None:
        if not 1 <= radius <= config.fov // 2:
            raise ConfigError(f"radius={radius!r} is not allowed: 1 <= radius <= {config.fov // 2} (half the view)")
        if not 0 < worth <= 1:
            raise ConfigError(f"worth={worth!r} is not allowed: 0 < worth <= 1 (a share of the prior's mean)")
        super().__init__(config, horizon=1, discount=discount, w_p=0.0, w_u=0.0, w_t=1.0, reach=2.0, seed=seed)
        self.radius, self.worth = int(radius), float(worth)
        self._floor = np.zeros(0)

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        super().reset(state, mask)
        if self._floor.shape != (state.n_worlds,):
            self._floor, mask = np.zeros(state.n_worlds), np.ones(state.n_worlds, bool)
        self._floor[mask] = self.worth * self.prior_information(state)[mask]

    def fill(self, state: WorldState, fallback: np.ndarray, out: np.ndarray) -> None:
        path_greedy_actions(
            state.arrays(), self._params, self.remember(state), self.radius, self._floor, fallback, out, world_threads()
        )


@njit(cache=True)
def sweep_actions(pos, occupant, blocked, h, left, spacing, n_actions, fallback, out, dist, first, queue, claimed):
    """out (K, N) <- SweepCoverage's moves: each agent in turn to the nearest cell with left < 0.5... (docstring)."""
    for k in range(pos.shape[0]):
        claimed[:] = False
        for i in range(pos.shape[1]):
            r0, c0 = pos[k, i, 0] + h, pos[k, i, 1] + h
            reached = bfs(blocked, k, r0, c0, np.int64(-1), n_actions, dist, first, queue)
            out[k, i] = fallback[k, i]
            for q in range(1, reached):
                r, c = queue[q, 0], queue[q, 1]
                if left[k, r, c] > 0.5 and not claimed[r, c]:
                    a = first[r, c]
                    if occupant[k, r0 + MOVES[a, 0], c0 + MOVES[a, 1]] < 0:
                        out[k, i] = a
                    claimed[max(0, r - spacing) : r + spacing + 1, max(0, c - spacing) : c + spacing + 1] = True
                    break
            for q in range(reached):
                dist[queue[q, 0], queue[q, 1]] = -1


@dataclass
class SweepConfig(ControllerConfig):
    """Settings of `controller=sweep` (SweepCoverage's keyword arguments)."""

    name: str = "sweep"
    spacing: int = 2  # a claimed target keeps the next agents' targets this many cells away (Γ's radius)


class SweepCoverage(FallbackHeuristic):
    """Batched wall-aware coverage (module docstring); agents with nothing left to sweep move at random."""

    def __init__(self, config: WorldConfig, spacing: int = SweepConfig.spacing, seed: int | WorldStreams = 0) -> None:
        if not 0 <= spacing <= 16:
            raise ConfigError(f"spacing={spacing!r} is not allowed: 0 <= spacing <= 16 (cells)")
        super().__init__(config, seed)
        self.spacing = int(spacing)
        self.left = np.ones((0, 0, 0))  # (K, S, S) float64: what the team's footprints left of each cell
        self._scratch = None

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        if self.left.shape != state.p.shape:
            self.left, mask = np.ones(state.p.shape), np.ones(state.n_worlds, bool)
        self.left[mask] = 1.0

    def fill(self, state: WorldState, fallback: np.ndarray, out: np.ndarray) -> None:
        if self.left.shape != state.p.shape:
            self.reset(state, np.ones(state.n_worlds, bool))
        sweep_footprints(state.pos, state.halo, self.left, SUPPORT_DR, SUPPORT_DC, SUPPORT_G)
        side = state.blocked.shape[1]
        if self._scratch is None or self._scratch[0].shape != (side, side):
            self._scratch = (
                np.full((side, side), -1, np.int32),
                np.zeros((side, side), np.int64),
                np.zeros((side * side, 2), np.int64),
                np.zeros((side, side), np.bool_),
            )
        sweep_actions(
            state.pos,
            state.occupant,
            state.blocked,
            state.halo,
            self.left,
            self.spacing,
            self.config.n_actions,
            fallback,
            out,
            *self._scratch,
        )
