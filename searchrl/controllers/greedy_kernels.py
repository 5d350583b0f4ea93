"""Footprint-greedy's compiled scoring (searchrl/controllers/greedy.py says what it scores and why): the information
of a cell of an agent's belief, the values of every cell in an agent's view, a footprint's sum over them and the
batch kernel that moves every agent of a batch. `walls.PathGreedy` scores its walks with the same pieces."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from searchrl.world.footprint import GAMMA, SUPPORT_DC, SUPPORT_DR, SUPPORT_G
from searchrl.world.libm import power
from searchrl.world.parallel import chunk_count, chunk_span
from searchrl.world.seen import freshness


class GreedyParams(NamedTuple):
    """FootprintGreedy's settings as `greedy_actions` takes them."""

    moves: np.ndarray  # (A, 2) int64, MOVES
    n_actions: int  # A: 5, or 9 with diagonal moves
    gamma: np.ndarray  # (5, 5) float64, Γ
    horizon: int
    discount: float
    w_p: float
    w_u: float
    w_t: float
    fov_half: int  # half the field of view: what an agent sees lies within that many cells
    contested: float
    hedge: float  # ε: the information read off (1 − ε)·belief + ε·uniform, both as sensing has depleted them


class GreedyMemory(NamedTuple):
    """What greedy keeps per world and agent between steps (searchrl/world/seen.py for seen and known)."""

    reach: np.ndarray  # (K, S, S) float64, `reach_weights`
    seen: np.ndarray  # (K, N, S, S) float32, Π (1 − Γ) of the neighbours' footprints seen; (K, N, 0, 0) without `seen`
    known: np.ndarray  # (K, N, S, S) int32, step each agent last saw a cell's truth; (K, N, 0, 0) without `age`
    rates: np.ndarray  # (K,) float64, age · N · ΣΓ / free cells: how fast an evenly spread team senses a cell
    flat: np.ndarray  # (K,) float64, the prior's mean information per free cell (with `hedge`; else (0,))


@njit(cache=True)
def _moves_apart(dr, dc, diagonal):
    """Moves between two cells dr, dc apart: Chebyshev with diagonal moves, Manhattan without."""
    return max(abs(dr), abs(dc)) if diagonal else abs(dr) + abs(dc)


@njit(cache=True, inline="always")  # inlined: called per cell, on scalars (an inlined call's array arguments
def information(params, p, u, prior_p, flat_k, sp, su, seen, fresh):  # are counted in and out, ~100 ns a call)
    """I = w_p·p̂ + w_u·û + w_t·p̂·(1 − û) of one cell of an agent's belief, p and u there (`WorldState.belief`),
    p̂ = sp·p·seen·fresh, û = su·u·seen·fresh: the observation's scaling and the factors of what the neighbours it
    saw have sensed there (`seen`) and what unseen agents have likely sensed since it last saw the cell's truth
    (`fresh`), 1.0 where GreedyMemory keeps neither. With params.hedge = ε > 0: (1 − ε)·I + ε·flat_k·left, flat_k
    the prior's mean I per free cell and left = p / prior_p (prior_p: `WorldState.p` there), scaled alike, the share
    of the cell sensing has not yet cleared: greedy on a belief that keeps ε of its mass uniform, depleted by the
    same sensing."""
    p_hat, u_hat = p * sp, u * su
    left = p / prior_p if params.hedge > 0.0 and prior_p > 0.0 else 0.0
    p_hat, u_hat, left = p_hat * seen, u_hat * seen, left * seen
    p_hat, u_hat, left = p_hat * fresh, u_hat * fresh, left * fresh
    info = params.w_p * p_hat + params.w_u * u_hat + params.w_t * p_hat * max(0.0, 1.0 - u_hat)
    if params.hedge > 0.0:
        info = (1.0 - params.hedge) * info + params.hedge * flat_k * left
    return info


@njit(cache=True)
def cell_information(params, belief, prior, flat, sp, su, seen, known, rate, now, k, i, r, c):
    """`information` of agent i's belief at padded cell (r, c) of world k at step `now`, read off the arrays:
    belief and prior `WorldState.belief` and `.p`, flat, seen, known and rate GreedyMemory's (rate its rates[k])."""
    seen_factor = seen[k, i, r, c] if seen.shape[2] > 0 else 1.0
    fresh = freshness(rate, now, known[k, i, r, c]) if known.shape[2] > 0 else 1.0
    flat_k = flat[k] if params.hedge > 0.0 else 0.0
    return information(
        params, belief[k, i, 0, r, c], belief[k, i, 1, r, c], prior[k, r, c], flat_k, sp, su, seen_factor, fresh
    )


@njit(cache=True)
def view_scratch(params):
    """values (3, W, W) float64, W = 2·(fov_half + g) + 1, Γ of radius g: `view_values`' scratch, one per thread."""
    side = 2 * (params.fov_half + params.gamma.shape[0] // 2) + 1
    return np.zeros((3, side, side))


@njit(cache=True, inline="always")  # inlined: once per agent, so its arguments are not copied
def view_values(w, params, memory, k, i, r0, c0, others, n_others, values):
    """values (3, W, W) <- (x, reach, I) of every cell within params.fov_half rows and columns of agent i's padded
    position (r0, c0) in world k of w (`WorldState.arrays()`), what the agent sees, centred (`view_scratch`): I its
    belief's information (`cell_information`), reach `GreedyMemory.reach`, x = contested where one of the agents
    at others[:n_others] (rows, cols) is fewer moves away than (r0, c0), else 1. Zero on the cells off the grid
    and in the margin outside the view, where footprints centred in the view reach: they add nothing."""
    view, contested, diagonal = params.fov_half, params.contested, params.n_actions > 5
    belief, prior, sp, su, now = w.belief, w.p, w.obs_scale[k, 0], w.obs_scale[k, 1], w.t[k]
    reach, seen, known, flat = memory.reach, memory.seen, memory.known, memory.flat
    rate = memory.rates[k] if known.shape[2] > 0 else 0.0
    margin, side = values.shape[1] // 2 - view, belief.shape[3]
    has_seen, has_known, flat_k = seen.shape[2] > 0, known.shape[2] > 0, flat[k] if params.hedge > 0.0 else 0.0
    values[:] = 0.0
    for dr in range(-view, view + 1):
        for dc in range(-view, view + 1):
            rr, cc = r0 + dr, c0 + dc
            if rr < 0 or cc < 0 or rr >= side or cc >= side:
                continue
            x, mine = 1.0, _moves_apart(dr, dc, diagonal)
            for j in range(n_others):
                if _moves_apart(rr - others[j, 0], cc - others[j, 1], diagonal) < mine:
                    x = contested
                    break
            vr, vc = margin + view + dr, margin + view + dc
            values[0, vr, vc], values[1, vr, vc] = x, reach[k, rr, cc]
            # cell_information's reads, done here: a call taking the arrays would count them in and out per cell
            seen_factor = seen[k, i, rr, cc] if has_seen else 1.0
            fresh = freshness(rate, now, known[k, i, rr, cc]) if has_known else 1.0
            values[2, vr, vc] = information(
                params,
                belief[k, i, 0, rr, cc],
                belief[k, i, 1, rr, cc],
                prior[k, rr, cc],
                flat_k,
                sp,
                su,
                seen_factor,
                fresh,
            )


@njit(cache=True, inline="always")  # inlined: called per move and step ahead
def footprint_information(params, values, dr, dc):
    """Σ Γ(d)·x·reach·I over the footprint centred dr, dc away from the agent whose view `values` holds
    (`view_values`; |dr|, |dc| <= fov_half): what it would sense there, the cells it does not see counting 0."""
    gamma = params.gamma
    g = gamma.shape[0] // 2
    centre = values.shape[1] // 2
    total = 0.0
    for fr in range(-g, g + 1):
        for fc in range(-g, g + 1):
            weight = gamma[fr + g, fc + g]
            if weight > 0.0:  # terms in the order of Γ's rows, as a sum over the cells sensed
                r, c = centre + dr + fr, centre + dc + fc
                total += weight * values[0, r, c] * values[1, r, c] * values[2, r, c]
    return total


@njit(cache=True, parallel=True)
def greedy_actions(w, params, memory, fallback, out, threads):
    """out (K,N) int64 <- footprint-greedy actions of the agents of w (`WorldState.arrays()`) with settings `params`
    (GreedyParams) and `memory` (GreedyMemory, seen and known already brought to this step). fallback (K,N) int64:
    random moves used where nothing is sensed. The K·N agents (world-major) are shared among `threads` numba
    threads (`searchrl.world.parallel.world_threads()`), not the worlds: a team mix holds a few worlds of many
    agents. An agent's move reads the state and writes its own entry of `out` only, so the count changes no bit."""
    n_slots = out.shape[0] * out.shape[1]
    n_chunks = chunk_count(n_slots, n_slots, threads)
    if n_chunks == 1:  # in this thread: waking a worker for the only chunk would just add its wake-up
        _greedy_span(w, params, memory, fallback, out, np.int64(0), n_slots)
        return
    for chunk in prange(n_chunks):
        first, stop = chunk_span(chunk, n_chunks, 0, n_slots)
        _greedy_span(w, params, memory, fallback, out, first, stop)


@njit(cache=True)
def _greedy_span(w, params, memory, fallback, out, first, stop):
    """`greedy_actions` for the agents first..stop-1 of the K·N, world-major (agent i of world k is k·N + i)."""
    pos, occupant, blocked, h, moves, view = w.pos, w.occupant, w.blocked, w.halo, params.moves, params.fov_half
    others = np.empty(((2 * view + 1) ** 2, 2), np.int64)
    values = view_scratch(params)
    for slot in range(first, stop):
        k, i = slot // pos.shape[1], slot % pos.shape[1]
        r, c = pos[k, i, 0] + h, pos[k, i, 1] + h
        n_others = 0
        if params.contested != 1.0:  # the other agents in view, as channel 0 of the observation shows them
            for dr in range(-view, view + 1):
                for dc in range(-view, view + 1):
                    j = occupant[k, r + dr, c + dc]
                    if j >= 0 and j != i:
                        others[n_others, 0], others[n_others, 1] = r + dr, c + dc
                        n_others += 1
        view_values(w, params, memory, k, i, r, c, others, n_others, values)
        best, best_score = -1, 0.0
        for a in range(1, params.n_actions):
            mr, mc = moves[a, 0], moves[a, 1]
            if blocked[k, r + mr, c + mc] or occupant[k, r + mr, c + mc] >= 0:
                continue
            score, weight = 0.0, 1.0
            for t in range(1, params.horizon + 1):
                score += weight * footprint_information(params, values, t * mr, t * mc)
                weight *= params.discount
            if score > best_score:
                best, best_score = a, score
        out[k, i] = best if best >= 1 else fallback[k, i]


def reach_weights(blocked: np.ndarray, exponent: float) -> np.ndarray:
    """(K, S, S) float64 weights (Γ_total / Γ_reach)^exponent from blocked (K, S, S) bool, 0 on blocked cells.

    Γ_reach(x) = Σ_d Γ(d) over the offsets d with x − d free: the footprint mass an agent can put on cell x from
    the cells it can stand on. It is Γ_total inside the world and less on the edge (3.96 of 5.44), in a corner
    (2.85) and beside obstacles. Needs a halo of at least Γ's radius (the state's is half the field of view)."""
    g = GAMMA.shape[0] // 2
    free = ~blocked
    side = blocked.shape[-1]
    mass = np.zeros(blocked.shape, np.float64)
    for dr, dc, weight in zip(SUPPORT_DR, SUPPORT_DC, SUPPORT_G, strict=True):  # mass[x] += Γ(d) · free[x − d]
        mass[:, g : side - g, g : side - g] += weight * free[:, g - dr : side - g - dr, g - dc : side - g - dc]
    weights = np.zeros(blocked.shape, np.float64)
    np.divide(GAMMA.sum(), mass, out=weights, where=free & (mass > 0))
    return np.where(free, power(weights, float(exponent)), 0.0)  # searchrl/world/libm.py: why not numpy's power
