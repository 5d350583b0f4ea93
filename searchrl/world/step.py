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
    given WorldStreams. All of SPEC.md's phases, the rewards and the episode's tallies included, run in one
    compiled call whose worlds are shared among numba's threads: the Python side checks and draws (and brings the
    freshness maps up to date, where the world keeps them)."""
    actions = check_actions(config, state, actions)
    k, n = actions.shape
    threads = world_threads()
    scratch = kernels.scratch_grids(state.p.shape[1], threads)  # a slot per thread
    priority = rng.random((k, n))  # tie-break for contested cells
    detect = rng.random(state.target_valid.shape)  # one uniform per target slot
    result = StepResult(
        reward=np.empty((k, n), np.float32),
        terminated=np.empty(k, np.bool_),
        truncated=np.empty(k, np.bool_),
        collided=np.empty((k, n), np.bool_),
        targets_found=np.empty((k, n), np.int64),
        info_collected=np.empty((k, n), np.float64),
        comm_gain=np.empty((k, n), np.float64),
        comm_pairs=np.empty(k, np.int64),
    )
    out = (result.collided, result.targets_found, result.info_collected, np.empty((k, n), np.bool_),
           result.comm_pairs, result.comm_gain, result.reward, result.terminated, result.truncated)  # fmt: skip
    radii = np.array([config.explicit_area // 2, config.comm_range // 2], np.int64)
    step_worlds(state.arrays(), actions, priority, detect, MOVES, SUPPORT, config.sensing_rate(state.size), radii,
                config.communication, _reward_terms(config), config.max_steps, scratch, out, threads)  # fmt: skip
    update_freshness(config, state, 0, k)  # observation only: when each agent last saw a cell, what it saw sensed
    return result


def _reward_terms(config: WorldConfig) -> np.ndarray:
    """(5,) float64: step_reward, collision_reward, target_reward, ξ/λ and τ/λ, the coefficients of SPEC.md's
    reward (phase 6) in the order it adds them."""
    return np.array([config.step_reward, config.collision_reward, config.target_reward, config.xi / config.lam,
                     config.tau / config.lam], np.float64)  # fmt: skip


@njit(cache=CACHE, parallel=True)
def step_worlds(w, actions, priority, detect, moves, support, c_coef, radii, merge, reward_terms, max_steps, scratch,
                out, threads):  # fmt: skip
    """SPEC.md's step (move, detect, sense and sweep, refresh, communicate, reward, time) for every world of w, the
    worlds shared among numba's threads (searchrl/world/parallel.py). actions (K,N) int64, priority (K,N) and
    detect (K,T) float64 the step's draws, moves (A,2) int64, support a `Footprint`, c_coef (K,) float64 λk, radii
    (2,) int64 those of Φ and of communication, merge whether beliefs merge, reward_terms
    (`_reward_terms`), max_steps the episode's length, scratch a `Scratch`; out = (collided (K,N) bool, found_by
    (K,N) int64, collected (K,N) float64, stale (K,N) bool, comm_pairs (K,) int64, comm_gain (K,N) float64, reward
    (K,N) float32, terminated (K,) bool, truncated (K,) bool) is written; `threads` (`parallel.world_threads()`)
    bounds the chunks.

    Each thread runs the phases in turn over its span of worlds: a phase touches the rows of its own worlds only,
    so this equals running each phase over all worlds in turn.
    """
    n_worlds = actions.shape[0]
    n_chunks = chunk_count(n_worlds, scratch.claim.shape[0], threads)
    if n_chunks == 1:  # in this thread: waking a worker for the only chunk would just add its wake-up
        _step_span(w, actions, priority, detect, moves, support, c_coef, radii, merge, reward_terms, max_steps,
                   scratch, out, 0, 0, n_worlds)  # fmt: skip
        return
    for chunk in prange(n_chunks):
        first, stop = chunk_span(chunk, n_chunks, 0, n_worlds)
        _step_span(w, actions, priority, detect, moves, support, c_coef, radii, merge, reward_terms, max_steps,
                   scratch, out, chunk, first, stop)  # fmt: skip


@njit(cache=CACHE)
def _step_span(w, actions, priority, detect, moves, support, c_coef, radii, merge, reward_terms, max_steps, scratch,
               out, slot, first, stop):  # fmt: skip
    """`step_worlds` for worlds first..stop-1, with scratch slot `slot` and work space of its own."""
    collided, found_by, collected, stale, comm_pairs, comm_gain = out[:6]
    phi, comm_radius = radii[0], radii[1]
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
    _account(w, first, stop, reward_terms, max_steps, out, np.empty(n_agents), np.empty(n_agents))


@njit(cache=CACHE)
def _account(w, first, stop, reward_terms, max_steps, out, reward64, info64):
    """Phases 6 and 7 of SPEC.md for worlds first..stop-1: each agent's reward into out's reward (float32), the
    clock and the episode's end into out's terminated and truncated, and the episode's tallies. reward64 and info64
    (N,) float64 are work space. The terms are added in SPEC.md's order and the team's sums are numpy's
    (`numpy_sum`), so the figures are those of the same sums in numpy, bit for bit."""
    collided, found_by, collected, stale, comm_pairs, comm_gain, reward, terminated, truncated = out
    step_reward, collision_reward, target_reward, info_weight, comm_weight = reward_terms
    t, n_found, n_targets = w.t, w.n_found, w.n_targets  # fields read once (kernels.py: no view in the loops)
    ep_return, ep_info, ep_comm_pairs, ep_collisions, ep_stale = (w.ep_return, w.ep_info, w.ep_comm_pairs,
                                                                  w.ep_collisions, w.ep_stale)  # fmt: skip
    n_agents = reward64.shape[0]
    for k in range(first, stop):
        n_collided = n_stale = 0
        for i in range(n_agents):
            reward64[i] = (step_reward + collision_reward * collided[k, i] + target_reward * found_by[k, i]
                           + info_weight * collected[k, i] + comm_weight * comm_gain[k, i])  # fmt: skip
            reward[k, i] = np.float32(reward64[i])
            info64[i] = collected[k, i]
            n_collided += collided[k, i]
            n_stale += stale[k, i]
        t[k] += 1
        terminated[k] = n_found[k] == n_targets[k]
        truncated[k] = t[k] >= max_steps and not terminated[k]
        ep_return[k] += numpy_sum(reward64)
        ep_info[k] += numpy_sum(info64)
        ep_comm_pairs[k] += comm_pairs[k]
        ep_collisions[k] += n_collided
        ep_stale[k] += n_stale


@njit(cache=CACHE)
def numpy_sum(values):
    """values.sum() as numpy adds a contiguous float64 row (N,), so a tally made here equals
    numpy's bit for bit (tests/test_engine.py checks every length up to 1,100): numpy sums a row of up to 128 in
    eight partial sums (`_block_sum`) and a longer one as the sum of its halves, the first a multiple of 8 long.
    Those halves are walked with a stack, not by recursion: numba cannot load a cached recursive function
    (numba issue #6061: a segfault)."""
    count = values.shape[0]
    if count <= 128:
        return _block_sum(values, 0, count)
    starts, counts = np.empty(64, np.int64), np.empty(64, np.int64)  # a frame per half being summed
    stage, left = np.zeros(64, np.int64), np.empty(64, np.float64)  # 0: to do, 1: first half, 2: second half
    top, total = 0, 0.0
    starts[0], counts[0] = 0, count
    while top >= 0:
        n = counts[top]
        half = n // 2 - (n // 2) % 8
        if n <= 128:  # a block: its sum goes back to the frame below
            total = _block_sum(values, starts[top], n)
            top -= 1
        elif stage[top] == 0:
            stage[top] = 1
            top += 1
            starts[top], counts[top], stage[top] = starts[top - 1], half, 0
        elif stage[top] == 1:
            left[top], stage[top] = total, 2
            top += 1
            starts[top], counts[top], stage[top] = starts[top - 1] + half, n - half, 0
        else:
            total = left[top] + total
            top -= 1
    return total


@njit(cache=CACHE)
def _block_sum(values, first, count):
    """numpy's sum of a row of at most 128: in order below 8, else eight partial sums combined pairwise, then the
    remainder in order."""
    if count < 8:
        total = 0.0
        for i in range(first, first + count):
            total += values[i]
        return total
    r0, r1, r2, r3 = values[first], values[first + 1], values[first + 2], values[first + 3]
    r4, r5, r6, r7 = values[first + 4], values[first + 5], values[first + 6], values[first + 7]
    whole = first + count - count % 8
    for i in range(first + 8, whole, 8):
        r0 += values[i]
        r1 += values[i + 1]
        r2 += values[i + 2]
        r3 += values[i + 3]
        r4 += values[i + 4]
        r5 += values[i + 5]
        r6 += values[i + 6]
        r7 += values[i + 7]
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for j in range(whole, first + count):
        total += values[j]
    return total
