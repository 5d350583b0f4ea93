"""Compiled phases of one step (see SPEC.md). Each works the worlds first..stop-1 of a batch, one after the other:
`step.step_worlds` cuts the batch into such spans and shares them among numba's threads, so the Python side makes
one call per batch, never one per world, agent or cell. A phase reads and writes the rows of its own worlds only,
with scratch and work space of its own span that it leaves as it found them: that is what lets any thread step any
world with the same result.

Conventions: the state comes as one `w` (`WorldState.arrays()`: the WorldState fields, padded maps, unpadded
positions, `w.halo` the halo h); Γ's support as one `support` (`footprint.SUPPORT`: parallel arrays dr, dc, g of
the 13 non-zero cells of Γ, in row-major order); scratch grids as one slot of `scratch_grids`. A field of `w` is
read once per call and every element is indexed from the whole array, with no view taken in the loops: a view
counts a reference to its array atomically, on a counter that every thread working the same array would contend for.
A compiled function is called with the same argument types everywhere, all given by position: numba compiles it,
and all it calls, once per types, and types a constant as Literal[int](0) and a prange index as uint64, so these go
in as np.int64(...) (tests/test_structure.py; with them, a cold start compiled the step three to six times over).
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numba import njit

CACHE = True  # compiled code is cached next to the source, so later starts skip the compile


class Scratch(NamedTuple):
    """Scratch grids, one slot per thread that steps worlds at once (slot j: [j]); every phase leaves its slot as
    it found it."""

    claim: np.ndarray  # (slots, S, S) int32, -1
    surv: np.ndarray  # (slots, S, S) float64
    fsum: np.ndarray  # (slots, S, S) float64
    removed: np.ndarray  # (slots, 2, S, S) float64
    done: np.ndarray  # (slots, S, S) bool, False


@lru_cache(maxsize=8)
def scratch_grids(side: int, slots: int = 1) -> Scratch:
    """The scratch grids for maps of side S = `side`, `slots` of each, shared by every step of that side."""
    return Scratch(
        claim=np.full((slots, side, side), -1, np.int32),
        surv=np.empty((slots, side, side), np.float64),
        fsum=np.empty((slots, side, side), np.float64),
        removed=np.empty((slots, 2, side, side), np.float64),
        done=np.zeros((slots, side, side), np.bool_),
    )


@njit(cache=CACHE)
def move_agents(w, first, stop, actions, priority, moves, claim, target, candidate, collided):
    """Phase 1. actions (K,N) int64 index moves (A,2) int64; priority (K,N) float64 breaks ties. Updates w.pos
    (K,N,2) and w.occupant (K,S,S) in place; writes collided (K,N) bool.

    claim: (S,S) int32 filled with -1 (left as found); target (N,2) int64 and candidate (N,) bool are work space.
    A move is blocked by a blocked cell, by a cell occupied at the start of the step, or by a higher-priority mover
    aiming at the same cell.
    """
    pos, occupant, blocked, h = w.pos, w.occupant, w.blocked, w.halo
    n_agents = actions.shape[1]
    for k in range(first, stop):
        for i in range(n_agents):
            a = actions[k, i]
            r = pos[k, i, 0] + moves[a, 0] + h
            c = pos[k, i, 1] + moves[a, 1] + h
            target[i, 0] = r
            target[i, 1] = c
            collided[k, i] = False
            candidate[i] = False
            if a == 0:
                continue
            if blocked[k, r, c] or occupant[k, r, c] >= 0:
                collided[k, i] = True
                continue
            candidate[i] = True
            j = claim[r, c]
            if j < 0 or priority[k, i] > priority[k, j]:
                claim[r, c] = i
        for i in range(n_agents):
            if not candidate[i]:
                continue
            r, c = target[i, 0], target[i, 1]
            if claim[r, c] != i:
                collided[k, i] = True
        for i in range(n_agents):  # vacate first: a winner never lands on a cell that is being vacated
            if candidate[i] and not collided[k, i]:
                occupant[k, pos[k, i, 0] + h, pos[k, i, 1] + h] = -1
        for i in range(n_agents):
            if candidate[i]:
                r, c = target[i, 0], target[i, 1]
                claim[r, c] = -1
                if not collided[k, i]:
                    occupant[k, r, c] = i
                    pos[k, i, 0] = r - h
                    pos[k, i, 1] = c - h


@njit(cache=CACHE)
def detect_targets(w, first, stop, detect, support, cover_agent, cover_g, found_by):
    """Phase 2. Each unfound target is found with probability 1 - Π(1 - Γ_i) from one uniform draw (detect (K,T)
    float64), credited to the first agent (by index) whose cumulative threshold passes the draw. Updates
    w.target_found, w.found_grid and w.n_found; found_by (K,N) int64 is written. cover_agent (13,) int64 and
    cover_g (13,) float64 are work space.
    """
    target_pos, target_valid, target_found = w.target_pos, w.target_valid, w.target_found
    found_grid, n_found, occupant, h = w.found_grid, w.n_found, w.occupant, w.halo
    dr, dc, g = support.dr, support.dc, support.g
    n_targets = target_valid.shape[1]
    n_support = dr.shape[0]
    for k in range(first, stop):
        for i in range(found_by.shape[1]):
            found_by[k, i] = 0
        for q in range(n_targets):
            if not target_valid[k, q] or target_found[k, q]:
                continue
            r = target_pos[k, q, 0] + h
            c = target_pos[k, q, 1] + h
            m = 0
            for s in range(n_support):  # an agent at target - offset sees the target at offset
                a = occupant[k, r - dr[s], c - dc[s]]
                if a >= 0:
                    # insertion sort by agent index keeps the spec's index order
                    pos_ins = m
                    while pos_ins > 0 and cover_agent[pos_ins - 1] > a:
                        cover_agent[pos_ins] = cover_agent[pos_ins - 1]
                        cover_g[pos_ins] = cover_g[pos_ins - 1]
                        pos_ins -= 1
                    cover_agent[pos_ins] = a
                    cover_g[pos_ins] = g[s]
                    m += 1
            survive = 1.0
            for s in range(m):
                survive *= 1.0 - cover_g[s]
                if detect[k, q] < 1.0 - survive:
                    target_found[k, q] = True
                    found_grid[k, r, c] = True
                    n_found[k] += 1
                    found_by[k, cover_agent[s]] += 1
                    break


@njit(cache=CACHE)
def sense(w, first, stop, support, c_coef, surv, fsum, removed, done, collected):
    """Phase 3 (eq. 1-4). True maps w.p, w.u (K,S,S) decay by Π_i (1 - λkΓ_i) under overlapping footprints, c_coef
    (K,) float64 the λk of each world; each agent is credited the Γ-weighted share of what its cells lost.
    collected (K,N) float64 = M_p + M_u.

    Scratch (S,S): surv, fsum float64; removed (2,S,S) float64; done bool (all False on entry and exit).
    """
    p, u, pos, h = w.p, w.u, w.pos, w.halo
    dr, dc, g = support.dr, support.dc, support.g
    n_agents = pos.shape[1]
    n_support = dr.shape[0]
    for k in range(first, stop):
        for i in range(n_agents):  # agent index order: the product is taken in that order
            for s in range(n_support):
                r, c = pos[k, i, 0] + h + dr[s], pos[k, i, 1] + h + dc[s]
                f = c_coef[k] * g[s]
                if done[r, c]:  # `done` marks cells already started in this world
                    surv[r, c] *= 1.0 - f
                    fsum[r, c] += f
                else:
                    done[r, c] = True
                    surv[r, c] = 1.0 - f
                    fsum[r, c] = f
        for i in range(n_agents):
            for s in range(n_support):
                r, c = pos[k, i, 0] + h + dr[s], pos[k, i, 1] + h + dc[s]
                if not done[r, c]:
                    continue
                done[r, c] = False
                old_p, old_u = p[k, r, c], u[k, r, c]
                p[k, r, c] = np.float32(old_p * surv[r, c])
                u[k, r, c] = np.float32(old_u * surv[r, c])
                removed[0, r, c] = np.float64(old_p) - np.float64(p[k, r, c])
                removed[1, r, c] = np.float64(old_u) - np.float64(u[k, r, c])
        for i in range(n_agents):
            total = 0.0
            for s in range(n_support):
                r, c = pos[k, i, 0] + h + dr[s], pos[k, i, 1] + h + dc[s]
                if fsum[r, c] > 0.0:
                    total += (removed[0, r, c] + removed[1, r, c]) * (c_coef[k] * g[s]) / fsum[r, c]
            collected[k, i] = total


@njit(cache=CACHE)
def refresh_beliefs(w, first, stop, radius):
    """Phase 4. Copy the true maps w.p, w.u into each agent's belief w.belief (K,N,2,S,S) on its (2·radius+1)²
    explicit area Φ and grow the agent's belief box w.belief_box (K,N,4) and its news since the last merge
    w.belief_news (K,N,4) to cover it (searchrl/world/merge.py). (When it was last seen is kept by
    searchrl/world/seen.py.)"""
    belief, belief_box, news, p, u, pos, h = w.belief, w.belief_box, w.belief_news, w.p, w.u, w.pos, w.halo
    width = 2 * radius + 1
    for k in range(first, stop):
        for i in range(pos.shape[1]):
            r0 = pos[k, i, 0] + h - radius
            c0 = pos[k, i, 1] + h - radius
            for r in range(r0, r0 + width):
                for c in range(c0, c0 + width):
                    belief[k, i, 0, r, c] = p[k, r, c]
                for c in range(c0, c0 + width):
                    belief[k, i, 1, r, c] = u[k, r, c]
            belief_box[k, i, 0] = min(belief_box[k, i, 0], r0)
            belief_box[k, i, 1] = max(belief_box[k, i, 1], r0 + width - 1)
            belief_box[k, i, 2] = min(belief_box[k, i, 2], c0)
            belief_box[k, i, 3] = max(belief_box[k, i, 3], c0 + width - 1)
            news[k, i, 0], news[k, i, 1] = min(news[k, i, 0], r0), max(news[k, i, 1], r0 + width - 1)
            news[k, i, 2], news[k, i, 3] = min(news[k, i, 2], c0), max(news[k, i, 3], c0 + width - 1)
