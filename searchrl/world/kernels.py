"""Compiled phases of one step (see SPEC.md). Each function loops over worlds, agents and cells inside numba,
so the Python side makes one call per phase per batch, never one per agent or cell.

Conventions: arrays are the WorldState fields (padded maps, unpadded positions); `h` is the halo.
Footprint support is passed as parallel arrays (dr, dc, g) of the 13 non-zero cells of Γ, in row-major order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_CACHE = True  # compiled code is cached next to the source, so later starts skip the ~5 s compile


@njit(cache=_CACHE)
def move_agents(pos, occupant, blocked, actions, priority, moves, h, claim, collided):
    """Phase 1. Updates pos (K,N,2) and occupant (K,S,S) in place; writes collided (K,N) bool.

    claim: (S,S) int32 scratch filled with -1 (left as found). A move is blocked by a blocked cell, by a cell
    occupied at the start of the step, or by a higher-priority mover aiming at the same cell.
    """
    n_worlds, n_agents = actions.shape
    target = np.empty((n_agents, 2), np.int64)
    candidate = np.empty(n_agents, np.bool_)
    for k in range(n_worlds):
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


@njit(cache=_CACHE)
def detect_targets(
    target_pos, target_valid, target_found, found_grid, n_found, occupant, detect, dr, dc, g, h, found_by
):
    """Phase 2. Each unfound target is found with probability 1 - Π(1 - Γ_i) from one uniform draw, credited
    to the first agent (by index) whose cumulative threshold passes the draw. found_by (K,N) int64 is written.
    """
    n_worlds, n_targets = target_valid.shape
    n_support = dr.shape[0]
    cover_agent = np.empty(n_support, np.int64)
    cover_g = np.empty(n_support, np.float64)
    found_by[:] = 0
    for k in range(n_worlds):
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


@njit(cache=_CACHE)
def sense(p, u, pos, dr, dc, g, c_coef, h, surv, fsum, removed, done, collected):
    """Phase 3 (eq. 1-4). True maps decay by Π_i (1 - λkΓ_i) under overlapping footprints, c_coef (K,) float64
    the λk of each world; each agent is credited the Γ-weighted share of what its cells lost. collected (K,N)
    float64 = M_p + M_u.

    Scratch (S,S): surv, fsum float64; removed (2,S,S) float64; done bool (all False on entry and exit).
    """
    n_worlds, n_agents = pos.shape[0], pos.shape[1]
    n_support = dr.shape[0]
    for k in range(n_worlds):
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


@njit(cache=_CACHE)
def refresh_beliefs(belief, belief_box, belief_time, p, u, pos, t, radius, h):
    """Phase 4. Copy the true maps into each agent's belief on its (2·radius+1)² explicit area Φ and grow the
    agent's belief box to cover it. With `belief_time` allocated (not (K, N, 0, 0)) mark Φ as seen at step t + 1,
    the count this step ends with."""
    n_worlds, n_agents = pos.shape[0], pos.shape[1]
    width = 2 * radius + 1
    timed = belief_time.shape[2] > 0
    for k in range(n_worlds):
        for i in range(n_agents):
            r0 = pos[k, i, 0] + h - radius
            c0 = pos[k, i, 1] + h - radius
            for ch in range(2):
                src = p if ch == 0 else u
                for r in range(r0, r0 + width):
                    for c in range(c0, c0 + width):
                        belief[k, i, ch, r, c] = src[k, r, c]
            if timed:
                for r in range(r0, r0 + width):
                    for c in range(c0, c0 + width):
                        belief_time[k, i, r, c] = t[k] + 1
            box = belief_box[k, i]
            box[0] = min(box[0], r0)
            box[1] = max(box[1], r0 + width - 1)
            box[2] = min(box[2], c0)
            box[3] = max(box[3], c0 + width - 1)


@njit(cache=_CACHE)
def _find_neighbours(occupant, pos, k, radius, h, nbrs, n_nbrs):
    """Fill nbrs[i, :n_nbrs[i]] with the agents within Chebyshev distance `radius` of agent i in world k (index
    order of the scan, which is row-major). Returns the number of unordered neighbour pairs."""
    pairs = 0
    for i in range(pos.shape[1]):
        pr, pc = pos[k, i, 0] + h, pos[k, i, 1] + h
        m = 0
        for r in range(pr - radius, pr + radius + 1):
            for c in range(pc - radius, pc + radius + 1):
                j = occupant[k, r, c]
                if j >= 0 and j != i:
                    nbrs[i, m] = j
                    m += 1
                    if j > i:
                        pairs += 1
        n_nbrs[i] = m
    return pairs


@njit(cache=_CACHE)
def communicate(belief, belief_box, occupant, pos, radius, h, merge, comm_pairs, comm_gain):
    """Phase 5 (eq. 13-16). Counts unordered neighbour pairs (Chebyshev distance <= radius) into comm_pairs (K,)
    and, when `merge`, replaces each agent's belief by the elementwise min over itself and its direct
    neighbours, all read from the pre-merge beliefs. comm_gain (K,N) float64 receives ΔM_p + ΔM_u.

    Outside the union of its neighbours' belief boxes an agent's value is already the min (neighbours hold the
    prior there, which bounds every belief from above), so only that union is scanned. New values go to a
    buffer first and are written back afterwards: the update is simultaneous.
    """
    n_worlds, n_agents = pos.shape[0], pos.shape[1]
    nbrs = np.empty((n_agents, (2 * radius + 1) ** 2 - 1), np.int64)
    n_nbrs = np.empty(n_agents, np.int64)
    region = np.empty((n_agents, 4), np.int64)
    offset = np.empty(n_agents + 1, np.int64)
    comm_gain[:] = 0.0
    for k in range(n_worlds):
        comm_pairs[k] = _find_neighbours(occupant, pos, k, radius, h, nbrs, n_nbrs)
        if not merge or comm_pairs[k] == 0:
            continue
        offset[0] = 0
        for i in range(n_agents):
            r0, r1, c0, c1 = 1 << 30, -1, 1 << 30, -1
            for b in range(n_nbrs[i]):
                box = belief_box[k, nbrs[i, b]]
                r0, r1, c0, c1 = min(r0, box[0]), max(r1, box[1]), min(c0, box[2]), max(c1, box[3])
            region[i, 0], region[i, 1], region[i, 2], region[i, 3] = r0, r1, c0, c1
            cells = (r1 - r0 + 1) * (c1 - c0 + 1) if (n_nbrs[i] > 0 and r1 >= r0) else 0
            offset[i + 1] = offset[i] + 2 * cells
        buf = np.empty(offset[n_agents], np.float32)
        for i in range(n_agents):  # pass 1: new values from the pre-merge beliefs
            r0, r1, c0, c1 = region[i, 0], region[i, 1], region[i, 2], region[i, 3]
            if offset[i + 1] == offset[i]:
                continue
            width = c1 - c0 + 1
            at = offset[i]
            for ch in range(2):
                for r in range(r0, r1 + 1):
                    seg = buf[at : at + width]
                    seg[:] = belief[k, i, ch, r, c0 : c1 + 1]
                    for b in range(n_nbrs[i]):
                        other = belief[k, nbrs[i, b], ch, r, c0 : c1 + 1]
                        for c in range(width):
                            if other[c] < seg[c]:
                                seg[c] = other[c]
                    at += width
        for i in range(n_agents):  # pass 2: write back, ΔM, and grow the box
            r0, r1, c0, c1 = region[i, 0], region[i, 1], region[i, 2], region[i, 3]
            if offset[i + 1] == offset[i]:
                continue
            width = c1 - c0 + 1
            at = offset[i]
            gain = 0.0
            for ch in range(2):
                for r in range(r0, r1 + 1):
                    row = belief[k, i, ch, r]
                    for c in range(width):
                        new = buf[at + c]
                        if new < row[c0 + c]:
                            gain += np.float64(row[c0 + c]) - np.float64(new)
                            row[c0 + c] = new
                    at += width
            comm_gain[k, i] = gain
            box = belief_box[k, i]
            box[0], box[1] = min(box[0], r0), max(box[1], r1)
            box[2], box[3] = min(box[2], c0), max(box[3], c1)


@njit(cache=_CACHE)
def observe_into(occupant, blocked, found_grid, belief, obs_scale, belief_time, belief_seen, age_rate, t, pos,
                 size, n_targets, n_found, h, maps, vec):  # fmt: skip
    """Observation of §3.2.1 into maps (K,N,C,F,F) float32 and vec (K,N,3) float32 (see SPEC.md). Where
    age_rate[k] > 0 the freshness exp(−age_rate·(t − belief_time)), times belief_seen where that is allocated (not
    (K, N, 0, 0)), scales the belief channels (C = 5) or fills channel 5 (C = 6).

    Written channel by channel so every inner loop runs over contiguous memory. (A numba `prange` over agents
    was 15x slower on the 2-core machine: thread wake-ups cost more than the work.)
    """
    n_worlds, n_agents = pos.shape[0], pos.shape[1]
    fov = maps.shape[3]
    half = fov // 2
    as_channel = maps.shape[2] > 5  # a sixth channel (observe.n_channels) holds the freshness
    with_seen = belief_seen.shape[2] > 0
    for flat in range(n_worlds * n_agents):
        k, i = flat // n_agents, flat % n_agents
        sp, su = obs_scale[k, 0], obs_scale[k, 1]
        r0 = pos[k, i, 0] + h - half
        c0 = pos[k, i, 1] + h - half
        out = maps[k, i]
        occ, blk, fnd = occupant[k], blocked[k], found_grid[k]
        bel_p, bel_u = belief[k, i, 0], belief[k, i, 1]
        for a in range(fov):
            r = r0 + a
            for b in range(fov):
                out[0, a, b] = occ[r, c0 + b] >= 0
            for b in range(fov):
                out[1, a, b] = blk[r, c0 + b]
            for b in range(fov):
                out[2, a, b] = fnd[r, c0 + b]
            for b in range(fov):
                out[3, a, b] = bel_p[r, c0 + b] * sp
            for b in range(fov):
                out[4, a, b] = bel_u[r, c0 + b] * su
        if age_rate[k] > 0.0:
            seen_at = belief_time[k, i]
            for a in range(fov):
                r = r0 + a
                for b in range(fov):
                    fresh = np.float32(np.exp(-age_rate[k] * (t[k] - seen_at[r, c0 + b])))
                    if with_seen:
                        fresh *= belief_seen[k, i, r, c0 + b]
                    if as_channel:
                        out[5, a, b] = fresh
                    else:
                        out[3, a, b] *= fresh
                        out[4, a, b] *= fresh
        out[0, half, half] = 0.0  # the agent itself stands at the centre and is not shown
        vec[k, i, 0] = pos[k, i, 1] / size[k]
        vec[k, i, 1] = pos[k, i, 0] / size[k]
        vec[k, i, 2] = (n_targets[k] - n_found[k]) / n_targets[k] if n_targets[k] > 0 else 0.0
