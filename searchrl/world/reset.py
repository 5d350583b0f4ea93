"""Per-world reset (§4.1): draw a scenario and write it into the batched state, other worlds untouched."""

from __future__ import annotations

import numpy as np

from searchrl.world.config import WorldConfig
from searchrl.world.footprint import team_sensing_rate
from searchrl.world.maps import gaussian_mixture, probability_map, uncertainty_map
from searchrl.world.seen import update_freshness
from searchrl.world.state import WorldState

_MAX_TARGET_ROUNDS = 1_000


def keep_probability(u: np.ndarray) -> np.ndarray:
    """The second stage of §4.1.4's placement: a tentative cell is kept with probability 1 - u/max(u) (the paper's
    `1 - u` needs u on a [0, 1] scale and u sums to 1, so we read it relative to its maximum). Same shape as u."""
    return 1.0 - u / u.max()


def place_targets(p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """Two-stage placement of §4.1.4 on distinct free cells.

    A tentative cell is drawn from p over the free cells, then kept when a uniform draw is below
    `keep_probability(u)`. A tentative cell that already holds a target is redrawn (rejection from p restricted
    to empty cells). Candidates are drawn in batches of `4 · count` from one CDF. p, u, free: (n, n).
    Returns (count, 2) int64 (row, col).
    """
    n = p.shape[0]
    cdf = np.cumsum(np.where(free, p, 0.0).ravel())
    keep_prob = keep_probability(u).ravel()
    chosen: list[int] = []
    taken: set[int] = set()
    for _ in range(_MAX_TARGET_ROUNDS):
        batch = 4 * count
        cells = np.minimum(np.searchsorted(cdf, rng.random(batch) * cdf[-1], side="right"), n * n - 1)
        keep = rng.random(batch) < keep_prob[cells]
        for cell in cells[keep].tolist():
            if cell not in taken:
                taken.add(cell)
                chosen.append(cell)
                if len(chosen) == count:
                    return np.stack(np.divmod(np.array(chosen, np.int64), n), axis=1)
    raise RuntimeError(f"could not place {count} targets in {_MAX_TARGET_ROUNDS} batches (maps too peaked?)")


def _unit_scale(peak: np.float32) -> np.float32:
    """The largest float32 s with peak·s <= 1 in float32, so scaled beliefs stay inside the [0, 1] Box."""
    scale = np.float32(1.0) / np.float32(peak)
    while np.float32(peak) * scale > np.float32(1.0):
        scale = np.nextafter(scale, np.float32(0.0))
    return scale


def _draw_obstacles(
    density: float, n: int, room: int, rng: np.random.Generator, k: int
) -> tuple[np.ndarray | None, np.ndarray]:
    """(obstacles or None, free) (n, n): iid obstacles at `density`, redrawn until `room` cells stay free."""
    if density <= 0:
        return None, np.ones((n, n), bool)
    for _ in range(100):
        obstacles = rng.random((n, n)) < density
        if (~obstacles).sum() >= room:
            return obstacles, ~obstacles
    raise RuntimeError(f"world {k}: 100 obstacle draws at density {density} left fewer than {room} free cells")


def draw_scenario_sizes(config: WorldConfig, rng: np.random.Generator) -> tuple[int, int, int]:
    """(n, m, j) drawn uniformly from the inclusive config ranges."""
    n = int(rng.integers(config.world_size[0], config.world_size[1] + 1))
    m = int(rng.integers(config.n_distributions[0], config.n_distributions[1] + 1))
    j = int(rng.integers(config.n_targets[0], config.n_targets[1] + 1))
    return n, m, j


def reset_world(config: WorldConfig, state: WorldState, k: int, rng: np.random.Generator) -> None:
    """Draw a fresh scenario for world k in place: maps, obstacles, targets, agents, beliefs, counters."""
    n, m, j = draw_scenario_sizes(config, rng)
    h = state.halo
    inner = (k, slice(h, h + n), slice(h, h + n))

    p = probability_map(
        gaussian_mixture(n, m, config.prob_variance_scale * n, config.variance_floor, config.rho_max, rng),
        config.eta,
    )
    u = uncertainty_map(
        gaussian_mixture(n, m, config.unc_variance_scale * n, config.variance_floor, config.rho_max, rng)
    )
    obstacles, free = _draw_obstacles(config.obstacle_density, n, state.n_agents + j, rng, k)
    n_agents = state.n_agents
    if obstacles is not None:  # no target can sit on an obstacle, so it carries no information
        p, u = np.where(free, p, 0.0), np.where(free, u, 0.0)
        p, u = p / p.sum(), u / u.sum()
    targets = place_targets(p, u, free, j, rng)
    free_for_agents = free.copy()
    free_for_agents[targets[:, 0], targets[:, 1]] = False
    start = rng.choice(np.flatnonzero(free_for_agents.ravel()), size=n_agents, replace=False)
    pos = np.stack(np.divmod(start.astype(np.int64), n), axis=1)  # (N, 2)

    state.size[k] = n
    state.t[k] = 0
    state.p[k] = 0.0
    state.u[k] = 0.0
    state.p[inner] = p
    state.u[inner] = u
    state.blocked[k] = True
    state.blocked[inner] = ~free
    state.age_rate[k] = config.belief_age * team_sensing_rate(state.blocked[k : k + 1], n_agents)[0]
    state.belief[k, :, 0] = state.p[k]  # every agent starts from the prior (§3.2.1)
    state.belief[k, :, 1] = state.u[k]
    side = state.p.shape[1]
    state.belief_box[k] = (side, -1, side, -1)  # empty: beliefs equal the prior
    state.pos[k] = pos
    state.occupant[k] = -1
    state.occupant[k, pos[:, 0] + h, pos[:, 1] + h] = np.arange(n_agents, dtype=np.int32)
    state.belief_time[k] = 0  # both are (K, N, 0, 0), and this a no-op, in a world that keeps neither
    state.belief_seen[k] = 1.0
    update_freshness(config, state, k, k + 1)  # the first observation already counts the neighbours in view
    state.target_valid[k] = False
    state.target_found[k] = False
    state.target_valid[k, :j] = True
    state.target_pos[k] = 0
    state.target_pos[k, :j] = targets
    state.found_grid[k] = False
    state.n_targets[k] = j
    state.n_found[k] = 0
    state.obs_scale[k] = (_unit_scale(state.p[inner].max()), _unit_scale(state.u[inner].max()))
    if state.target_weight.shape[1] > 0:  # info_reward="targets": p·weight sums to 1 over the world
        keep = np.where(free, keep_probability(u), 0.0)
        state.target_weight[k] = 0.0
        state.target_weight[inner] = keep / (p * keep).sum()
    state.ep_return[k] = 0.0
    state.ep_comm_pairs[k] = 0
    state.ep_info[k] = 0.0
    state.ep_collisions[k] = 0


def reset_worlds(config: WorldConfig, state: WorldState, mask: np.ndarray, rng: np.random.Generator) -> None:
    """Reset the worlds where `mask` (K,) is true, in index order, leaving the others untouched."""
    for k in np.flatnonzero(mask):
        reset_world(config, state, int(k), rng)
