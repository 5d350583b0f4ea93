"""Per-world reset (§4.1): draw a world (sizes, prior, then the scenario's obstacles and targets) and write it into
the batched state, other worlds untouched. The order of the draws is searchrl/world/scenario.py's spec."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from searchrl.world.config import WorldConfig
from searchrl.world.footprint import team_sensing_rate
from searchrl.world.kernels import CACHE
from searchrl.world.parallel import chunk_count, chunk_span, world_threads
from searchrl.world.scenario import PAPER, Scenario
from searchrl.world.seen import update_freshness
from searchrl.world.state import WorldState
from searchrl.world.truth import rows_cols


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


@dataclass(frozen=True)
class DrawnWorld:
    """What a reset draws for one world of side n: the prior p and u (n, n) float64 the agents start from (summing
    to 1 over the free cells), free (n, n) bool (not an obstacle), the agents' start cells pos (N, 2) int64 and the
    targets (j, 2) int64. Writing it into a batch (`write_world`) draws nothing, so a map drawn once can start
    several episodes."""

    p: np.ndarray
    u: np.ndarray
    free: np.ndarray
    pos: np.ndarray
    targets: np.ndarray


def draw_world(config: WorldConfig, n_agents: int, rng: np.random.Generator, scenario: Scenario = PAPER) -> DrawnWorld:
    """Draw a world for `n_agents` agents: sizes, prior maps, the scenario's obstacles and targets, start cells."""
    scenario = scenario.pick(rng)  # a mix draws which scenario (searchrl/world/scenario.py), a scenario nothing
    n, m, j = draw_scenario_sizes(config, rng)
    prior = scenario.prior(config, n, m, rng)
    obstacles = scenario.obstacles(n, n_agents + j, rng)
    free = np.ones((n, n), bool) if obstacles is None else ~obstacles
    maps = (prior.p, prior.u, prior.truth_p, prior.truth_u)
    if obstacles is not None:  # no target can sit on an obstacle, so it carries no information
        maps = tuple(np.where(free, x, 0.0) / np.where(free, x, 0.0).sum() for x in maps)
    p, u, truth_p, truth_u = maps
    targets = scenario.targets(truth_p, truth_u, free, j, rng)
    # numpy draws a choice from the free cells left as the same choice of their indices (its `take` of them)
    index = rng.choice(int(free.sum()) - len(targets), size=n_agents, replace=False)
    return DrawnWorld(p, u, free, _start_cells(free, targets, index), targets)


def write_world(config: WorldConfig, state: WorldState, k: int, world: DrawnWorld) -> None:
    """World k of `state` starts an episode in the drawn `world`: maps, obstacles, agents, targets, every belief
    the prior, counters at 0."""
    p_peak, u_peak = _write_world(
        state.arrays(), k, world.p, world.u, world.free, world.pos, world.targets, world_threads()
    )
    if config.belief_age > 0:  # else 0: the rate (a count of free cells) is not needed
        state.age_rate[k] = config.belief_age * team_sensing_rate(state.blocked[k : k + 1], state.n_agents)[0]
    state.belief_time[k] = 0  # both are (K, N, 0, 0), and this a no-op, in a world that keeps neither
    state.belief_seen[k] = 1.0
    update_freshness(config, state, k, k + 1)  # the first observation already counts the neighbours in view
    state.obs_scale[k] = (_unit_scale(p_peak), _unit_scale(u_peak))


def reset_world(
    config: WorldConfig, state: WorldState, k: int, rng: np.random.Generator, scenario: Scenario = PAPER
) -> None:
    """Draw a fresh world k in place (`draw_world`, then `write_world`)."""
    write_world(config, state, k, draw_world(config, state.n_agents, rng, scenario))


@njit(cache=CACHE)
def _start_cells(free, targets, index):
    """(N, 2) int64: the index[i]-th (N,) int64 of the free cells (n, n) bool without a target (targets (j, 2)
    int64), counted row by row, as (row, col)."""
    left = free.copy()
    for t in range(targets.shape[0]):
        left[targets[t, 0], targets[t, 1]] = False
    return rows_cols(np.flatnonzero(left)[index], free.shape[0])


@njit(cache=CACHE, parallel=True)
def _write_world(w, k, p, u, free, pos, targets, threads):
    """Write world k of w (`WorldState.arrays()`) in one compiled call: its side, the prior p and u (n, n) float64
    as float32 inside the halo and 0 outside, the cells blocked outside `free` (n, n) bool and on the halo, every
    agent's belief the prior (an empty belief box), the agents at pos (N, 2) int64, the targets (j, 2) int64 to
    find, and the clock, age rate and episode tallies at 0. The agents' beliefs, most of what is written (N · 2 · S²
    values), are cut into up to `threads` chunks of agents, one run in the calling thread (no parallel region).
    belief_time, belief_seen and obs_scale are left to the caller. Returns the largest p and u written (float32)."""
    state_p, state_u, blocked, occupant, found_grid, swept = w.p, w.u, w.blocked, w.occupant, w.found_grid, w.swept
    agent_pos, target_pos, target_valid, target_found = w.pos, w.target_pos, w.target_valid, w.target_found
    n, h, side = p.shape[0], w.halo, state_p.shape[1]  # fields read once (kernels.py: no view in the loops)
    w.size[k], w.t[k], w.age_rate[k] = n, 0, 0.0
    p_peak, u_peak = np.float32(0.0), np.float32(0.0)
    for r in range(side):
        for c in range(side):
            inside = h <= r < h + n and h <= c < h + n
            state_p[k, r, c] = p[r - h, c - h] if inside else 0.0
            state_u[k, r, c] = u[r - h, c - h] if inside else 0.0
            p_peak, u_peak = max(p_peak, state_p[k, r, c]), max(u_peak, state_u[k, r, c])
            blocked[k, r, c] = not free[r - h, c - h] if inside else True
            occupant[k, r, c] = -1
            found_grid[k, r, c] = False
            swept[k, r, c] = False
    n_agents = pos.shape[0]
    n_chunks = chunk_count(n_agents, n_agents, threads)
    if n_chunks == 1:
        _write_beliefs(w, k, np.int64(0), n_agents)
    else:
        for chunk in prange(n_chunks):
            first, stop = chunk_span(chunk, n_chunks, 0, n_agents)
            _write_beliefs(w, k, first, stop)
    for i in range(n_agents):
        agent_pos[k, i, 0], agent_pos[k, i, 1] = pos[i, 0], pos[i, 1]
        occupant[k, pos[i, 0] + h, pos[i, 1] + h] = i
    for s in range(target_valid.shape[1]):
        real = s < targets.shape[0]
        target_valid[k, s], target_found[k, s] = real, False
        target_pos[k, s, 0] = targets[s, 0] if real else 0
        target_pos[k, s, 1] = targets[s, 1] if real else 0
    w.n_targets[k], w.n_found[k] = targets.shape[0], 0
    w.merged[k] = False  # no merge yet: every neighbour is new to the first (merge.py)
    w.ep_return[k], w.ep_comm_pairs[k], w.ep_info[k], w.ep_collisions[k], w.ep_stale[k] = 0.0, 0, 0.0, 0, 0
    return p_peak, u_peak


@njit(cache=CACHE)
def _write_beliefs(w, k, first, stop):
    """Agents first..stop-1 of world k start from the prior (§3.2.1): their beliefs w.p[k] and w.u[k], an empty
    belief box (the belief equals the prior) and no news of a merge (merge.py)."""
    state_p, state_u, belief, belief_box, news, merge_pos = w.p, w.u, w.belief, w.belief_box, w.belief_news, w.merge_pos
    side = state_p.shape[1]
    for i in range(first, stop):
        for r in range(side):
            for c in range(side):
                belief[k, i, 0, r, c] = state_p[k, r, c]
                belief[k, i, 1, r, c] = state_u[k, r, c]
        belief_box[k, i, 0], belief_box[k, i, 1] = side, -1
        belief_box[k, i, 2], belief_box[k, i, 3] = side, -1
        news[k, i, 0], news[k, i, 1], news[k, i, 2], news[k, i, 3] = side, -1, side, -1
        merge_pos[k, i, 0], merge_pos[k, i, 1] = 0, 0  # as allocated: no merge yet


def reset_worlds(
    config: WorldConfig, state: WorldState, mask: np.ndarray, rng: np.random.Generator, scenario: Scenario = PAPER
) -> None:
    """Reset the worlds where `mask` (K,) is true, in index order, leaving the others untouched."""
    for k in np.flatnonzero(mask):
        reset_world(config, state, int(k), rng, scenario)
