"""One step of K worlds × N agents (the rules are in SPEC.md beside this file)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit, prange

from searchrl.world import kernels
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import MOVES, SUPPORT
from searchrl.world.kernels import CACHE
from searchrl.world.merge import merge_work
from searchrl.world.parallel import agent_blocks, chunk_count, chunk_span, world_threads
from searchrl.world.seen import update_freshness
from searchrl.world.state import WorldState
from searchrl.world.step_spans import MERGE_BLOCK_AGENTS, StepInputs, step_sharing_merges, step_span
from searchrl.world.streams import WorldStreams


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
    if actions.dtype.kind not in "iu":  # the integer kinds, as np.issubdtype(dtype, np.integer) says, without its cost
        raise ValueError(f"actions have dtype {actions.dtype}; expected integers in [0, {config.n_actions})")
    if actions.size and not _in_range(actions.reshape(-1), config.n_actions):
        raise ValueError(f"actions range over [{actions.min()}, {actions.max()}]; allowed [0, {config.n_actions - 1}]")
    return actions.astype(np.int64, copy=False)


@njit(cache=CACHE)
def _in_range(actions, n_actions):
    """Whether every one of actions (M,) (any integer dtype) is in [0, n_actions): one pass, where min and max make
    two."""
    for a in actions:
        if a < 0 or a >= n_actions:
            return False
    return True


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
    out = (
        result.collided,
        result.targets_found,
        result.info_collected,
        np.empty((k, n), np.bool_),
        result.comm_pairs,
        result.comm_gain,
        result.reward,
        result.terminated,
        result.truncated,
    )
    sensing, radii, reward_terms = _step_terms(config)
    work = merge_work(threads, n, config.comm_range // 2)  # a slot per thread
    step_worlds(
        state.arrays(),
        actions,
        priority,
        detect,
        MOVES,
        SUPPORT,
        sensing,
        radii,
        config.communication,
        reward_terms,
        config.max_steps,
        scratch,
        work,
        out,
        threads,
    )
    update_freshness(config, state, 0, k)  # observation only: when each agent last saw a cell, what it saw sensed
    return result


@lru_cache(maxsize=16)
def _step_terms(config: WorldConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The config's numbers `step_worlds` reads, made once per config (read-only): sensing (3,) float64 λ, k and
    k_per_n (a world of side n senses at c = λ·(k + k_per_n·n), `WorldConfig.sensing_rate`); radii (2,) int64 those
    of Φ and of communication; reward_terms (5,) float64 step_reward, collision_reward, target_reward, ξ/λ and
    τ/λ, the coefficients of SPEC.md's reward (phase 6) in the order it adds them."""
    sensing = np.array([config.lam, config.k, config.k_per_n], np.float64)
    radii = np.array([config.explicit_area // 2, config.comm_range // 2], np.int64)
    reward_terms = np.array(
        [
            config.step_reward,
            config.collision_reward,
            config.target_reward,
            config.xi / config.lam,
            config.tau / config.lam,
        ],
        np.float64,
    )
    for terms in (sensing, radii, reward_terms):
        terms.flags.writeable = False
    return sensing, radii, reward_terms


@njit(cache=CACHE, parallel=True)
def step_worlds(
    w,
    actions,
    priority,
    detect,
    moves,
    support,
    sensing,
    radii,
    merge,
    reward_terms,
    max_steps,
    scratch,
    work,
    out,
    threads,
):
    """SPEC.md's step (move, detect, sense and sweep, refresh, communicate, reward, time) for every world of w, the
    worlds shared among numba's threads (searchrl/world/parallel.py). actions (K,N) int64, priority (K,N) and detect
    (K,T) float64 the step's draws, moves (A,2) int64, support a `Footprint`, sensing, radii and reward_terms those of
    `_step_terms`, merge whether beliefs merge, max_steps the episode's length, scratch a `Scratch` and work a
    `merge.MergeWork` (a slot per thread each); out = (collided (K,N) bool, found_by (K,N) int64, collected (K,N)
    float64, stale (K,N) bool, comm_pairs (K,) int64, comm_gain (K,N) float64, reward (K,N) float32, terminated (K,)
    bool, truncated (K,) bool) is written; `threads` (`parallel.world_threads()`) bounds the chunks.

    Each thread runs the phases in turn over its span of worlds: a phase touches the rows of its own worlds only,
    so this equals running each phase over all worlds in turn. With fewer worlds than threads, the merges are
    shared among the threads as well (`step_spans.step_sharing_merges`).
    """
    n_worlds, size = actions.shape[0], w.size
    c_coef = np.empty(n_worlds)  # each world's λk, as `WorldConfig.sensing_rate` computes it
    for k in range(n_worlds):
        c_coef[k] = sensing[0] * (sensing[1] + sensing[2] * np.float64(size[k]))
    n_chunks = chunk_count(n_worlds, scratch.claim.shape[0], threads)
    blocks = agent_blocks(n_worlds, actions.shape[1], threads, MERGE_BLOCK_AGENTS) if merge else 1
    s = StepInputs(actions, priority, detect, moves, support, c_coef, radii, merge, reward_terms, max_steps)
    if blocks > 1:  # fewer worlds than threads: each world's merge is shared among them too
        step_sharing_merges(w, s, scratch, work, out, blocks)
    elif n_chunks == 1:  # in this thread: waking a worker for the only chunk would just add its wake-up
        step_span(w, s, scratch, work, out, np.int64(0), np.int64(0), n_worlds)
    else:
        for chunk in prange(n_chunks):
            first, stop = chunk_span(chunk, n_chunks, 0, n_worlds)
            step_span(w, s, scratch, work, out, np.int64(chunk), first, stop)
