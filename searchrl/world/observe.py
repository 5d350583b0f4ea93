"""Agent observations (§3.2.1): a (5, fov, fov) field of view (6 with `belief_age_channel`) and a 3-vector."""

from __future__ import annotations

import numpy as np

from searchrl.world import kernels
from searchrl.world.config import WorldConfig
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
    kernels.observe_into(
        state.occupant, state.blocked, state.found_grid, state.belief, state.obs_scale, state.belief_time,
        state.belief_seen, state.age_rate, state.t, state.pos, state.size, state.n_targets, state.n_found,
        state.halo, maps, vec,
    )  # fmt: skip
    return maps, vec
