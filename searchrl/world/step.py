"""One step of K worlds × N agents (the rules are in SPEC.md beside this file)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from searchrl.world import kernels
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import MOVES, SUPPORT
from searchrl.world.kernels import CACHE
from searchrl.world.parallel import chunk_count, chunk_span, world_threads
from searchrl.world.seen import update_freshness
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams
from searchrl.world.swept import sweep


@dataclass
class StepResult:
    """What one step produced, per agent (K, N) or per world (K,)."""

    reward: np.ndarray  # (K, N) float32, Table 1 + eq. 5 + eq. 17
    terminated: np.ndarray  # (K,) bool, all targets found
    truncated: np.ndarray  # (K,) bool, max_steps reached with targets left
    collided: np.ndarray  # (K, N) bool, move blocked this step
    targets_found: np.ndarray  # (K, N) int64, targets credited to each agent this step
    info_collected: np.ndarray  # (K, N) float64, M_p + M_u (eq. 3-4)
    comm_gain: np.ndarray  # (K, N) float64, ΔM_p + ΔM_u (eq. 15-16)
    comm_pairs: np.ndarray  # (K,) int64, unordered neighbour pairs this step

    @property
    def done(self) -> np.ndarray:
        """(K,) bool: the world's episode ended this step."""
        return self.terminated | self.truncated


def check_actions(config: WorldConfig, state: WorldState, actions: np.ndarray) -> np.ndarray:
    """(K, N) int64 actions, or a ValueError naming the problem (the kernels do not bounds-check)."""
    actions = np.asarray(actions)
    expected = (state.n_worlds, state.n_agents)
    if actions.shape != expected:
        raise ValueError(f"actions have shape {actions.shape}; expected (n_worlds, n_agents) = {expected}")
    if not np.issubdtype(actions.dtype, np.integer):
        raise ValueError(f"actions have dtype {actions.dtype}; expected integers in [0, {config.n_actions})")
    if actions.size and (actions.min() < 0 or actions.max() >= config.n_actions):
        raise ValueError(f"actions range over [{actions.min()}, {actions.max()}]; allowed [0, {config.n_actions - 1}]")
    return actions.astype(np.int64, copy=False)


def step(
    config: WorldConfig, state: WorldState, actions: np.ndarray, rng: np.random.Generator | WorldStreams
) -> StepResult:
    """Advance every world one step in place. actions: (K, N) ints in [0, config.n_actions); `rng` draws the
    contested-cell tie-breaks (K, N) and the detection uniforms (K, targets), world k's from its own stream when
    given WorldStreams."""
    actions = check_actions(config, state, actions)
    k, n = actions.shape
    w = state.arrays()
    threads = world_threads()
    scratch = kernels.scratch_grids(state.p.shape[1], threads)  # a slot per thread
    priority = rng.random((k, n))  # tie-break for contested cells
    detect = rng.random(state.target_valid.shape)  # one uniform per target slot

    collided = np.empty((k, n), np.bool_)
    targets_found = np.empty((k, n), np.int64)
    info = np.empty((k, n), np.float64)
    stale = np.empty((k, n), np.bool_)
    comm_pairs = np.empty(k, np.int64)
    comm_gain = np.empty((k, n), np.float64)
    out = (collided, targets_found, info, stale, comm_pairs, comm_gain)
    phi, comm_radius = config.explicit_area // 2, config.comm_range // 2
    step_worlds(w, actions, priority, detect, MOVES, SUPPORT, config.sensing_rate(state.size), phi, comm_radius,
                config.communication, scratch, out, threads)  # fmt: skip

    reward64 = (
        config.step_reward
        + config.collision_reward * collided
        + config.target_reward * targets_found
        + (config.xi / config.lam) * info
        + (config.tau / config.lam) * comm_gain
    )
    state.t += 1
    update_freshness(config, state, 0, k)  # observation only: when each agent last saw a cell, what it saw sensed
    terminated = state.n_found == state.n_targets
    truncated = (state.t >= config.max_steps) & ~terminated
    state.ep_return += reward64.sum(axis=1)
    state.ep_info += info.sum(axis=1)
    state.ep_comm_pairs += comm_pairs
    state.ep_collisions += collided.sum(axis=1)
    state.ep_stale += stale.sum(axis=1)
    return StepResult(
        reward=reward64.astype(np.float32),
        terminated=terminated,
        truncated=truncated,
        collided=collided,
        targets_found=targets_found,
        info_collected=info,
        comm_gain=comm_gain,
        comm_pairs=comm_pairs,
    )


@njit(cache=CACHE, parallel=True)
def step_worlds(w, actions, priority, detect, moves, support, c_coef, phi, comm_radius, merge, scratch, out, threads):
    """Phases 1-5 of SPEC.md (move, detect, sense and sweep, refresh, communicate) for every world of w, the worlds
    shared among numba's threads (searchrl/world/parallel.py). actions (K,N) int64, priority
    (K,N) and detect (K,T) float64 the step's draws, moves (A,2) int64, support a `Footprint`, c_coef (K,) float64
    λk, phi and comm_radius the radii of Φ and of communication, merge whether beliefs merge, scratch a `Scratch`;
    out = (collided (K,N) bool, found_by (K,N) int64, collected (K,N) float64, stale (K,N) bool, comm_pairs (K,)
    int64, comm_gain (K,N) float64) is written; `threads` (`parallel.world_threads()`) bounds the chunks.

    Each thread runs the five phases in turn over its span of worlds: a phase touches the rows of its own worlds
    only, so this equals running each phase over all worlds in turn.
    """
    n_worlds = actions.shape[0]
    n_chunks = chunk_count(n_worlds, scratch.claim.shape[0], threads)
    if n_chunks == 1:  # in this thread: waking a worker for the only chunk would just add its wake-up
        _step_span(w, actions, priority, detect, moves, support, c_coef, phi, comm_radius, merge, scratch, out, 0,
                   0, n_worlds)  # fmt: skip
        return
    for chunk in prange(n_chunks):
        first, stop = chunk_span(chunk, n_chunks, 0, n_worlds)
        _step_span(w, actions, priority, detect, moves, support, c_coef, phi, comm_radius, merge, scratch, out,
                   chunk, first, stop)  # fmt: skip


@njit(cache=CACHE)
def _step_span(w, actions, priority, detect, moves, support, c_coef, phi, comm_radius, merge, scratch, out, slot,
               first, stop):  # fmt: skip
    """`step_worlds` for worlds first..stop-1, with scratch slot `slot` and work space of its own."""
    collided, found_by, collected, stale, comm_pairs, comm_gain = out
    n_agents, n_support = actions.shape[1], support.dr.shape[0]
    target, candidate = np.empty((n_agents, 2), np.int64), np.empty(n_agents, np.bool_)
    cover_agent, cover_g = np.empty(n_support, np.int64), np.empty(n_support, np.float64)
    nbrs = np.empty((n_agents, (2 * comm_radius + 1) ** 2 - 1), np.int64)
    n_nbrs, region, offset = np.empty(n_agents, np.int64), np.empty((n_agents, 4), np.int64), np.empty(
        n_agents + 1, np.int64)  # fmt: skip
    claim, surv, fsum = scratch.claim[slot], scratch.surv[slot], scratch.fsum[slot]
    removed, done = scratch.removed[slot], scratch.done[slot]
    kernels.move_agents(w, first, stop, actions, priority, moves, claim, target, candidate, collided)
    kernels.detect_targets(w, first, stop, detect, support, cover_agent, cover_g, found_by)
    kernels.sense(w, first, stop, support, c_coef, surv, fsum, removed, done, collected)
    sweep(w, first, stop, support, stale)
    kernels.refresh_beliefs(w, first, stop, phi)
    kernels.communicate(w, first, stop, comm_radius, merge, nbrs, n_nbrs, region, offset, comm_pairs, comm_gain)
