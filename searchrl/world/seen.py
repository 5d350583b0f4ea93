"""Belief freshness: how much of what an agent believes of a cell still holds. The one implementation behind the
world's observation (`WorldConfig.belief_age`, `belief_seen`) and footprint-greedy's memory (`age`, `seen`,
searchrl/controllers/greedy.py), so a policy sees the factor that teacher scores.

Two per-agent maps, each (K, N, S, S) or (K, N, 0, 0) where it is not kept:
- known (int32): the step at which the agent last saw the cell's truth, inside its explicit area Φ (0: never).
  Outside Φ its belief has stood still since while the team went on sensing, so it counts
  `freshness(rate, t, known)` = exp(−rate·(t − known)) times, rate = age·ρ and ρ = N·ΣΓ / free cells the rate
  at which an evenly spread team senses a cell (`team_sensing_rate`).
- seen (float32): the product of (1 − Γ) over the footprints of the neighbours the agent saw in its field of view.
  A neighbour in view has just sensed its footprint, and sensing scales p and u of each cell there by (1 − Γ)
  (eq. 1 with λk = 1); without merging (model C) the agent's belief never hears of it otherwise.

`remember_sightings` brings both up to date at the agents' current positions. The world calls it after each step
and at reset (so the first observation already counts the neighbours in view), greedy each time it acts, at the
same positions and step count, so the two keep the same maps. With `forget` seen goes back to 1 on Φ, where the
belief is the truth and already holds the neighbours' sensing: the world always forgets, greedy only with `age`
(without it greedy's seen keeps every footprint since the reset, as it always has).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from searchrl.world.config import WorldConfig
from searchrl.world.footprint import SUPPORT
from searchrl.world.kernels import CACHE
from searchrl.world.parallel import chunk_count, chunk_span, world_threads
from searchrl.world.state import WorldState


@njit(cache=CACHE)
def freshness(rate, now, then):
    """exp(−rate·(now − then)) as float64: what is left at step `now` of a belief last true at step `then`."""
    return np.exp(-rate * (now - then))


def remember_sightings(
    w, support, seen: np.ndarray, known: np.ndarray, view: int, phi: int, forget: bool, first: int, stop: int
) -> None:
    """Update seen and known (K,N,S,S), either (K,N,0,0) to skip it, of worlds first..stop-1 at the agents'
    positions in w (a `WorldArrays`): seen *= (1 − Γ) (support: a `Footprint`) under the footprint of every other
    agent within Chebyshev distance `view` of each agent, scanned row by row; then on the agent's Φ (radius `phi`)
    known = w.t[k] and, with `forget`, seen = 1. The worlds are shared among numba's threads
    (searchrl/world/parallel.py)."""
    _remember_sightings(w, support, seen, known, view, phi, forget, first, stop, world_threads())


@njit(cache=CACHE, parallel=True)
def _remember_sightings(w, support, seen, known, view, phi, forget, first, stop, threads):
    """`remember_sightings` on up to `threads` threads."""
    n_chunks = chunk_count(stop - first, stop - first, threads)
    if n_chunks == 1:  # in this thread (one world after a reset, say): no parallel region to start
        _remember_span(w, support, seen, known, view, phi, forget, first, stop)
        return
    for chunk in prange(n_chunks):
        start, end = chunk_span(chunk, n_chunks, first, stop)
        _remember_span(w, support, seen, known, view, phi, forget, start, end)


@njit(cache=CACHE)
def _remember_span(w, support, seen, known, view, phi, forget, first, stop):
    """`remember_sightings` for worlds first..stop-1, in this thread; no view taken in the loops (kernels.py)."""
    pos, occupant, t, h = w.pos, w.occupant, w.t, w.halo
    dr, dc, g = support.dr, support.dc, support.g
    use_seen, use_known = seen.shape[2] > 0, known.shape[2] > 0
    for k in range(first, stop):
        for i in range(pos.shape[1]):
            r0, c0 = pos[k, i, 0] + h, pos[k, i, 1] + h
            if use_seen:
                for r in range(r0 - view, r0 + view + 1):
                    for c in range(c0 - view, c0 + view + 1):
                        j = occupant[k, r, c]
                        if j >= 0 and j != i:
                            for s in range(g.shape[0]):
                                seen[k, i, r + dr[s], c + dc[s]] *= 1.0 - g[s]
                if forget:
                    for r in range(r0 - phi, r0 + phi + 1):
                        for c in range(c0 - phi, c0 + phi + 1):
                            seen[k, i, r, c] = 1.0
            if use_known:
                for r in range(r0 - phi, r0 + phi + 1):
                    for c in range(c0 - phi, c0 + phi + 1):
                        known[k, i, r, c] = t[k]


def update_freshness(config: WorldConfig, state: WorldState, first: int, stop: int) -> None:
    """`remember_sightings` on state.belief_seen and state.belief_time of worlds first..stop-1, after a step (all
    of them) or a reset (one); nothing when the world keeps neither."""
    if state.belief_seen.size or state.belief_time.size:
        remember_sightings(
            state.arrays(),
            SUPPORT,
            state.belief_seen,
            state.belief_time,
            config.fov // 2,
            config.explicit_area // 2,
            True,
            first,
            stop,
        )
