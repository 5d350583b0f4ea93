"""One step of K worlds × N agents (the rules are in SPEC.md beside this file)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from searchrl.world import kernels
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import MOVES, SUPPORT
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
    scratch = kernels.scratch_grids(state.p.shape[1])
    priority = rng.random((k, n))  # tie-break for contested cells
    detect = rng.random(state.target_valid.shape)  # one uniform per target slot

    collided = np.empty((k, n), np.bool_)
    kernels.move_agents(w, actions, priority, MOVES, scratch, collided)

    targets_found = np.empty((k, n), np.int64)
    kernels.detect_targets(w, detect, SUPPORT, targets_found)

    info = np.empty((k, n), np.float64)
    kernels.sense(w, SUPPORT, config.sensing_rate(state.size), scratch, info)
    stale = np.empty((k, n), np.bool_)
    sweep(w, SUPPORT, stale)

    kernels.refresh_beliefs(w, config.explicit_area // 2)

    comm_pairs = np.empty(k, np.int64)
    comm_gain = np.empty((k, n), np.float64)
    kernels.communicate(w, config.comm_range // 2, config.communication, comm_pairs, comm_gain)

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
