"""Phase 5 of SPEC.md (eq. 13-16): each agent's neighbours, and the merge of their beliefs by elementwise min.

What a merge scans. Agent i's new belief is the min, cell by cell, of its own and its neighbours' beliefs, all read
before the merge. Outside a neighbour's belief box its belief is the prior, which bounds every belief from above,
so only the union of the neighbours' boxes can change. Within that union, a neighbour j that was also i's
neighbour at the world's last merge can lower i's belief only where one of the two beliefs changed since: that
merge left i's belief at most j's everywhere, and since then j's has changed only on its news (`belief_news`: what
that merge lowered and its Φ refreshes since). i's own Φ refresh set its belief there to the truth, which no
belief is below (the truth only loses information: tests/test_invariants.py). So i scans the bounding rectangle of
its new neighbours' boxes and its kept neighbours' news, within the union.

The result is the whole union's, bit for bit: the same new values; the same ΔM, since the cells that change are
the same ones, visited in the same row-major order; the same boxes, grown by the whole union. A team that stays
together scans what changed since the last step instead of everything its members have seen
(`python -m searchrl.bench world` times it). A world that was just reset (`merged` false) knows no last merge,
and treats every neighbour as new.

A merge comes in three pieces: `plan_merge` (a world's neighbours and each agent's rectangles), `merge_values`
(pass 1: the new values into a buffer, all read before any is written) and `write_merge` (pass 2: each agent
writes its own rows). The passes work any block of agents, so a world's merge can be shared among threads
(`step.step_worlds`); `communicate` runs the three for each world of a span in turn.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numba import njit

from searchrl.world.kernels import CACHE

_FAR = 1 << 30  # the first corner of an empty rectangle: any cell's row and column are smaller


class MergeWork(NamedTuple):
    """The merge's work space, one slot per world merged at once (slot s: [s]); every entry is written before it
    is read."""

    nbrs: np.ndarray  # (slots, N, (2·radius+1)² − 1) int64: each agent's neighbours
    n_nbrs: np.ndarray  # (slots, N) int64: how many
    region: np.ndarray  # (slots, N, 4) int64: the union of the neighbours' boxes (r0, r1, c0, c1), inclusive
    scan: np.ndarray  # (slots, N, 4) int64: what can change within it
    offset: np.ndarray  # (slots, N + 1) int64: where each agent's new values start in the merge's buffer


@lru_cache(maxsize=8)
def merge_work(slots: int, n_agents: int, radius: int) -> MergeWork:
    """The work space for `slots` worlds of n_agents agents at communication radius `radius`, shared by every step
    of that shape (as `kernels.scratch_grids`)."""
    return MergeWork(
        nbrs=np.empty((slots, n_agents, (2 * radius + 1) ** 2 - 1), np.int64),
        n_nbrs=np.empty((slots, n_agents), np.int64),
        region=np.empty((slots, n_agents, 4), np.int64),
        scan=np.empty((slots, n_agents, 4), np.int64),
        offset=np.empty((slots, n_agents + 1), np.int64),
    )


@njit(cache=CACHE)
def _find_neighbours(w, k, radius, work, slot):
    """Fill nbrs[slot, i, :n_nbrs[slot, i]] with the agents within Chebyshev distance `radius` of agent i in world k
    (index order of the scan, which is row-major). Returns the number of unordered neighbour pairs."""
    occupant, pos, h = w.occupant, w.pos, w.halo
    nbrs, n_nbrs = work.nbrs, work.n_nbrs
    pairs = 0
    for i in range(pos.shape[1]):
        pr, pc = pos[k, i, 0] + h, pos[k, i, 1] + h
        m = 0
        for r in range(pr - radius, pr + radius + 1):
            for c in range(pc - radius, pc + radius + 1):
                j = occupant[k, r, c]
                if j >= 0 and j != i:
                    nbrs[slot, i, m] = j
                    m += 1
                    if j > i:
                        pairs += 1
        n_nbrs[slot, i] = m
    return pairs


@njit(cache=CACHE)
def _kept(merge_pos, k, i, j, radius):
    """Whether agents i and j of world k were neighbours (Chebyshev distance <= radius) at its last merge."""
    return max(abs(merge_pos[k, i, 0] - merge_pos[k, j, 0]), abs(merge_pos[k, i, 1] - merge_pos[k, j, 1])) <= radius


@njit(cache=CACHE)
def _plan(w, k, i, radius, known, work, slot):
    """Agent i's rectangles (r0, r1, c0, c1), inclusive, padded: region[i] the union of its neighbours' boxes (its
    box grows by it) and scan[i] what can change within it (the module's docstring). Returns the cells of scan[i]."""
    belief_box, news, merge_pos = w.belief_box, w.belief_news, w.merge_pos
    nbrs, n_nbrs, region, scan = work.nbrs, work.n_nbrs, work.region, work.scan
    r0, r1, c0, c1 = _FAR, -1, _FAR, -1
    s0, s1, t0, t1 = _FAR, -1, _FAR, -1
    for b in range(n_nbrs[slot, i]):
        j = nbrs[slot, i, b]
        r0, r1 = min(r0, belief_box[k, j, 0]), max(r1, belief_box[k, j, 1])
        c0, c1 = min(c0, belief_box[k, j, 2]), max(c1, belief_box[k, j, 3])
        if known and _kept(merge_pos, k, i, j, radius):  # only j's news can be below i's belief
            s0, s1 = min(s0, news[k, j, 0]), max(s1, news[k, j, 1])
            t0, t1 = min(t0, news[k, j, 2]), max(t1, news[k, j, 3])
        else:  # anywhere in j's box
            s0, s1 = min(s0, belief_box[k, j, 0]), max(s1, belief_box[k, j, 1])
            t0, t1 = min(t0, belief_box[k, j, 2]), max(t1, belief_box[k, j, 3])
    region[slot, i, 0], region[slot, i, 1], region[slot, i, 2], region[slot, i, 3] = r0, r1, c0, c1
    s0, s1, t0, t1 = max(s0, r0), min(s1, r1), max(t0, c0), min(t1, c1)
    scan[slot, i, 0], scan[slot, i, 1], scan[slot, i, 2], scan[slot, i, 3] = s0, s1, t0, t1
    return (s1 - s0 + 1) * (t1 - t0 + 1) if (s1 >= s0 and t1 >= t0) else 0


@njit(cache=CACHE)
def plan_merge(w, k, radius, merge, work, slot, comm_pairs, comm_gain):
    """World k's neighbours and, when `merge`, what each agent scans (in work slot `slot`), w.merged[k] then set;
    comm_pairs[k] the unordered neighbour pairs, comm_gain[k] zeroed. Returns the length of the merge's buffer of
    new values (agent i's at offset[slot, i]..offset[slot, i + 1]: two channels of its scan)."""
    n_agents = w.pos.shape[1]
    offset = work.offset
    for i in range(n_agents):
        comm_gain[k, i] = 0.0
    comm_pairs[k] = _find_neighbours(w, k, radius, work, slot)
    offset[slot, 0] = 0
    if not merge:
        return 0
    known = w.merged[k]
    for i in range(n_agents):
        offset[slot, i + 1] = offset[slot, i] + 2 * _plan(w, k, i, radius, known, work, slot)
    w.merged[k] = True  # read by the plan alone; the passes that follow record this merge's news and positions
    return offset[slot, n_agents]


@njit(cache=CACHE)
def merge_values(w, k, first, stop, work, slot, buf, base):
    """Pass 1 for agents first..stop-1 of world k: the min over each agent's and its neighbours' beliefs on its
    scan into buf[base + offset[slot, i]:], all read before any is written (the update is simultaneous)."""
    belief = w.belief
    nbrs, n_nbrs, scan, offset = work.nbrs, work.n_nbrs, work.scan, work.offset
    for i in range(first, stop):
        if offset[slot, i + 1] == offset[slot, i]:
            continue
        s0, s1, c0 = scan[slot, i, 0], scan[slot, i, 1], scan[slot, i, 2]
        width = scan[slot, i, 3] - c0 + 1
        at = base + offset[slot, i]
        for ch in range(2):
            for r in range(s0, s1 + 1):
                for c in range(width):
                    buf[at + c] = belief[k, i, ch, r, c0 + c]
                for b in range(n_nbrs[slot, i]):
                    j = nbrs[slot, i, b]
                    for c in range(width):
                        if belief[k, j, ch, r, c0 + c] < buf[at + c]:
                            buf[at + c] = belief[k, j, ch, r, c0 + c]
                at += width


@njit(cache=CACHE)
def write_merge(w, k, first, stop, work, slot, buf, base, comm_gain):
    """Pass 2 for agents first..stop-1 of world k: write back what pass 1 lowered, its ΔM into comm_gain[k, i], the
    cells lowered as the agent's news, its box grown by its region, its position as of this merge. Each agent
    writes its own rows only."""
    belief, belief_box, news, merge_pos, pos = w.belief, w.belief_box, w.belief_news, w.merge_pos, w.pos
    region, scan, offset = work.region, work.scan, work.offset
    for i in range(first, stop):
        n0, n1, m0, m1 = _FAR, -1, _FAR, -1  # the cells this merge lowers
        if offset[slot, i + 1] != offset[slot, i]:
            s0, s1, c0 = scan[slot, i, 0], scan[slot, i, 1], scan[slot, i, 2]
            width = scan[slot, i, 3] - c0 + 1
            at = base + offset[slot, i]
            gain = 0.0
            for ch in range(2):
                for r in range(s0, s1 + 1):
                    for c in range(width):
                        new, old = buf[at + c], belief[k, i, ch, r, c0 + c]
                        if new < old:
                            gain += np.float64(old) - np.float64(new)
                            belief[k, i, ch, r, c0 + c] = new
                            n0, n1, m0, m1 = min(n0, r), max(n1, r), min(m0, c0 + c), max(m1, c0 + c)
                    at += width
            comm_gain[k, i] = gain
        r0, r1, c0, c1 = region[slot, i, 0], region[slot, i, 1], region[slot, i, 2], region[slot, i, 3]
        if r1 >= r0:
            belief_box[k, i, 0], belief_box[k, i, 1] = min(belief_box[k, i, 0], r0), max(belief_box[k, i, 1], r1)
            belief_box[k, i, 2], belief_box[k, i, 3] = min(belief_box[k, i, 2], c0), max(belief_box[k, i, 3], c1)
        news[k, i, 0], news[k, i, 1], news[k, i, 2], news[k, i, 3] = n0, n1, m0, m1
        merge_pos[k, i, 0], merge_pos[k, i, 1] = pos[k, i, 0], pos[k, i, 1]


@njit(cache=CACHE)
def communicate(w, first, stop, radius, merge, work, slot, comm_pairs, comm_gain):
    """Phase 5 (eq. 13-16) for worlds first..stop-1, one after the other, in work slot `slot`. Counts unordered
    neighbour pairs (Chebyshev distance <= radius) into comm_pairs (K,) int64 and, when `merge`, replaces each
    agent's belief w.belief by the elementwise min over itself and its direct neighbours, all read from the
    pre-merge beliefs. comm_gain (K,N) float64 receives ΔM_p + ΔM_u.

    Each agent scans only what can change (the module's docstring). New values go to a buffer first and are
    written back afterwards: the update is simultaneous. A merge leaves each agent's news (w.belief_news) the
    cells it lowered, and its position in w.merge_pos, for the next one.
    """
    n_agents = w.pos.shape[1]
    for k in range(first, stop):
        size = plan_merge(w, k, radius, merge, work, slot, comm_pairs, comm_gain)
        if not merge:
            continue
        buf = np.empty(size, np.float32)
        merge_values(w, k, np.int64(0), n_agents, work, slot, buf, np.int64(0))
        write_merge(w, k, np.int64(0), n_agents, work, slot, buf, np.int64(0), comm_gain)
