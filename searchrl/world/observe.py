"""Agent observations (§3.2.1): a (5, fov, fov) field of view (6 with `belief_age_channel`) and a 3-vector."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from searchrl.world.config import WorldConfig
from searchrl.world.kernels import CACHE
from searchrl.world.parallel import agent_blocks, block_span, chunk_count, chunk_span, world_threads
from searchrl.world.seen import freshness
from searchrl.world.state import WorldState

N_CHANNELS = 5  # other agents, obstacles/out of bounds, found targets, belief p, belief u
VECTOR_SIZE = 3  # col / n, row / n, remaining targets / targets


def n_channels(config: WorldConfig) -> int:
    """Channels of the field of view: 5, or 6 with `belief_age_channel` (the belief's freshness)."""
    return N_CHANNELS + int(config.belief_age_channel)


def observation_buffers(config: WorldConfig, n_worlds: int) -> tuple[np.ndarray, np.ndarray]:
    """Empty (maps (K, N, C, fov, fov), vector (K, N, 3)) float32 buffers for `observe(..., out=...)`, C =
    `n_channels(config)`."""
    shape = (n_worlds, config.n_agents)
    return (
        np.empty((*shape, n_channels(config), config.fov, config.fov), np.float32),
        np.empty((*shape, VECTOR_SIZE), np.float32),
    )


def observe(
    config: WorldConfig, state: WorldState, out: tuple[np.ndarray, np.ndarray] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Observations of every agent: maps (K, N, C, fov, fov) float32 (C = `n_channels(config)`) and vector
    (K, N, 3) float32.

    p and u are scaled by 1 / max of the world's prior map, so the prior peaks at 1 in every world whatever
    its size (the raw maps sum to 1 and shrink as 1/n²). With `config.belief_age` > 0 they also show how stale the
    agent's belief of each cell is (`WorldConfig.belief_age`; with `belief_seen` also what the neighbours it saw
    have sensed), by scaling them or, with `belief_age_channel`, in a sixth channel. Pass `out` to reuse buffers.
    """
    maps, vec = observation_buffers(config, state.n_worlds) if out is None else out
    observe_into(state.arrays(), maps, vec, world_threads())
    return maps, vec


def observe_worlds(
    config: WorldConfig, state: WorldState, out: tuple[np.ndarray, np.ndarray], worlds: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """`observe` of the worlds listed in `worlds` (int64 indices) into `out`, the others' rows left as they are:
    after a step has observed every world and a few were reset, only those have changed."""
    maps, vec = out
    _observe_listed(state.arrays(), maps, vec, np.asarray(worlds, np.int64))
    return maps, vec


@njit(cache=CACHE)
def _observe_listed(w, maps, vec, worlds):
    for k in worlds:  # a few worlds: in this thread, no parallel region to start
        _observe_span(w, maps, vec, k, k + 1, np.int64(0), maps.shape[1])


# The fewest agents of a block when a batch of fewer worlds than threads shares its worlds' agents among the
# threads: an agent's observation copies a few hundred cells, so a smaller block costs more to hand over than it does.
OBSERVE_BLOCK_AGENTS = 64


@njit(cache=CACHE, parallel=True)
def observe_into(w, maps, vec, threads):
    """Observation of §3.2.1 of the state w (`WorldState.arrays()`) into maps (K,N,C,F,F) float32 and vec (K,N,3)
    float32 (see SPEC.md), on up to `threads` threads. Where w.age_rate[k] > 0 the freshness
    exp(−age_rate·(t − belief_time)), times belief_seen where that is kept (not (K, N, 0, 0)), scales the belief
    channels (C = 5) or fills channel 5 (C = 6).

    The worlds are shared among numba's threads (searchrl/world/parallel.py), a whole world to a thread; a batch of
    fewer worlds than threads shares blocks of at least `OBSERVE_BLOCK_AGENTS` agents (a `prange` over single
    agents was 15x slower on two cores, its thread wake-ups costing more than the work).
    """
    n_worlds, n_agents = maps.shape[0], maps.shape[1]
    blocks = agent_blocks(n_worlds, n_agents, threads, OBSERVE_BLOCK_AGENTS)
    if blocks > 1:
        for job in prange(n_worlds * blocks):
            k, first, stop = block_span(job, blocks, n_agents)
            _observe_span(w, maps, vec, k, k + 1, first, stop)
        return
    n_chunks = chunk_count(n_worlds, n_worlds, threads)
    if n_chunks == 1:  # in this thread: no parallel region to start
        _observe_span(w, maps, vec, np.int64(0), n_worlds, np.int64(0), n_agents)
        return
    for chunk in prange(n_chunks):
        first, stop = chunk_span(chunk, n_chunks, 0, n_worlds)
        _observe_span(w, maps, vec, first, stop, np.int64(0), n_agents)


@njit(cache=CACHE)
def _observe_span(w, maps, vec, first, stop, agent_first, agent_stop):
    """`observe_into` for worlds first..stop-1, their agents agent_first..agent_stop-1, written
    channel by channel so every inner loop runs over contiguous memory. Every element is indexed from the whole
    arrays, with no view taken in the loops (see kernels.py: views count references to the shared arrays
    atomically, a counter all threads would contend for)."""
    occupant, blocked, found_grid, belief, obs_scale = w.occupant, w.blocked, w.found_grid, w.belief, w.obs_scale
    belief_time, belief_seen, age_rate, t, pos, h = w.belief_time, w.belief_seen, w.age_rate, w.t, w.pos, w.halo
    size, n_targets, n_found = w.size, w.n_targets, w.n_found
    fov = maps.shape[3]
    half = fov // 2
    as_channel = maps.shape[2] > 5  # a sixth channel (observe.n_channels) holds the freshness
    with_seen = belief_seen.shape[2] > 0
    for k in range(first, stop):
        sp, su = obs_scale[k, 0], obs_scale[k, 1]
        for i in range(agent_first, agent_stop):
            r0 = pos[k, i, 0] + h - half
            c0 = pos[k, i, 1] + h - half
            for a in range(fov):
                r = r0 + a
                for b in range(fov):
                    maps[k, i, 0, a, b] = occupant[k, r, c0 + b] >= 0
                for b in range(fov):
                    maps[k, i, 1, a, b] = blocked[k, r, c0 + b]
                for b in range(fov):
                    maps[k, i, 2, a, b] = found_grid[k, r, c0 + b]
                for b in range(fov):
                    maps[k, i, 3, a, b] = belief[k, i, 0, r, c0 + b] * sp
                for b in range(fov):
                    maps[k, i, 4, a, b] = belief[k, i, 1, r, c0 + b] * su
            if age_rate[k] > 0.0:
                for a in range(fov):
                    r = r0 + a
                    for b in range(fov):
                        fresh = np.float32(freshness(age_rate[k], t[k], belief_time[k, i, r, c0 + b]))
                        if with_seen:
                            fresh *= belief_seen[k, i, r, c0 + b]
                        if as_channel:
                            maps[k, i, 5, a, b] = fresh
                        else:
                            maps[k, i, 3, a, b] *= fresh
                            maps[k, i, 4, a, b] *= fresh
            maps[k, i, 0, half, half] = 0.0  # the agent itself stands at the centre and is not shown
            vec[k, i, 0] = pos[k, i, 1] / size[k]
            vec[k, i, 1] = pos[k, i, 0] / size[k]
            vec[k, i, 2] = (n_targets[k] - n_found[k]) / n_targets[k] if n_targets[k] > 0 else 0.0
