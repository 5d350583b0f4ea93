"""Hand-built single worlds for the scenario tests: every array written explicitly after `allocate`."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from searchrl.world.config import WorldConfig
from searchrl.world.state import WorldState, allocate

Cell = tuple[int, int]


def make_world(
    config: WorldConfig,
    n: int,
    agents: list[Cell],
    targets: list[Cell],
    obstacles: tuple[Cell, ...] = (),
    p: float | np.ndarray = 0.0,
    u: float | np.ndarray = 0.0,
) -> WorldState:
    """One world of side n; p and u are a constant per cell or an (n, n) array; beliefs start as the maps."""
    assert len(agents) == config.n_agents and 1 <= len(targets) <= config.n_targets[1]
    state = allocate(config, 1)
    h = state.halo
    inner = (0, slice(h, h + n), slice(h, h + n))
    state.size[0] = n
    state.p[inner] = p
    state.u[inner] = u
    state.blocked[0] = True
    state.blocked[inner] = False
    for r, c in obstacles:
        state.blocked[0, r + h, c + h] = True
    state.belief[0, :, 0] = state.p[0]
    state.belief[0, :, 1] = state.u[0]
    state.pos[0] = agents
    state.occupant[0] = -1
    for i, (r, c) in enumerate(agents):
        state.occupant[0, r + h, c + h] = i
    state.target_pos[0, : len(targets)] = targets
    state.target_valid[0, : len(targets)] = True
    state.n_targets[0] = len(targets)
    state.obs_scale[0] = (1.0, 1.0)
    return state


def draws(seed: int, n_agents: int, n_slots: int) -> tuple[np.ndarray, np.ndarray]:
    """What `step` will draw from default_rng(seed) for one world: (priority (N,), detect (T,))."""
    rng = np.random.default_rng(seed)
    return rng.random((1, n_agents))[0], rng.random((1, n_slots))[0]


def seed_where(condition: Callable[[np.ndarray, np.ndarray], bool], n_agents: int, n_slots: int) -> int:
    """The first seed whose draws satisfy `condition(priority, detect)`, so a scenario can pick its luck."""
    for seed in range(10_000):
        if condition(*draws(seed, n_agents, n_slots)):
            return seed
    raise AssertionError("no seed satisfies the condition")


def cfg(**kw: object) -> WorldConfig:
    """A small config for hand-built worlds; the world_size range only sets the allocation."""
    base = dict(world_size=(7, 7), n_distributions=(1, 1), n_targets=(1, 1), n_agents=1, fov=11)
    return WorldConfig(**{**base, **kw})
