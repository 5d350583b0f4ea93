"""Per-world reset (§4.1): draw a world (sizes, prior, then the scenario's obstacles and targets) and write it into
the batched state, other worlds untouched. The order of the draws is searchrl/world/scenario.py's spec."""

from __future__ import annotations

import numpy as np

from searchrl.world.config import WorldConfig
from searchrl.world.footprint import team_sensing_rate
from searchrl.world.scenario import PAPER, Scenario
from searchrl.world.seen import update_freshness
from searchrl.world.state import WorldState


def _unit_scale(peak: np.float32) -> np.float32:
    """The largest float32 s with peak·s <= 1 in float32, so scaled beliefs stay inside the [0, 1] Box."""
    scale = np.float32(1.0) / np.float32(peak)
    while np.float32(peak) * scale > np.float32(1.0):
        scale = np.nextafter(scale, np.float32(0.0))
    return scale


def draw_scenario_sizes(config: WorldConfig, rng: np.random.Generator) -> tuple[int, int, int]:
    """(n, m, j) drawn uniformly from the inclusive config ranges."""
    n = int(rng.integers(config.world_size[0], config.world_size[1] + 1))
    m = int(rng.integers(config.n_distributions[0], config.n_distributions[1] + 1))
    j = int(rng.integers(config.n_targets[0], config.n_targets[1] + 1))
    return n, m, j


def reset_world(
    config: WorldConfig, state: WorldState, k: int, rng: np.random.Generator, scenario: Scenario = PAPER
) -> None:
    """Draw a fresh world k in place: sizes, prior maps, the scenario's obstacles and targets, agents, beliefs,
    counters."""
    scenario = scenario.pick(rng)  # a mix draws which scenario (searchrl/world/scenario.py), a scenario nothing
    n, m, j = draw_scenario_sizes(config, rng)
    h = state.halo
    inner = (k, slice(h, h + n), slice(h, h + n))

    prior = scenario.prior(config, n, m, rng)
    n_agents = state.n_agents
    obstacles = scenario.obstacles(n, n_agents + j, rng)
    free = np.ones((n, n), bool) if obstacles is None else ~obstacles
    maps = (prior.p, prior.u, prior.truth_p, prior.truth_u)
    if obstacles is not None:  # no target can sit on an obstacle, so it carries no information
        maps = tuple(np.where(free, x, 0.0) / np.where(free, x, 0.0).sum() for x in maps)
    p, u, truth_p, truth_u = maps
    targets = scenario.targets(truth_p, truth_u, free, j, rng)
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
    state.swept[k] = False
    state.n_targets[k] = j
    state.n_found[k] = 0
    state.obs_scale[k] = (_unit_scale(state.p[inner].max()), _unit_scale(state.u[inner].max()))
    state.ep_return[k] = 0.0
    state.ep_comm_pairs[k] = 0
    state.ep_info[k] = 0.0
    state.ep_collisions[k] = 0
    state.ep_stale[k] = 0


def reset_worlds(config: WorldConfig, state: WorldState, mask: np.ndarray, rng: np.random.Generator,
                 scenario: Scenario = PAPER) -> None:  # fmt: skip
    """Reset the worlds where `mask` (K,) is true, in index order, leaving the others untouched."""
    for k in np.flatnonzero(mask):
        reset_world(config, state, int(k), rng, scenario)
