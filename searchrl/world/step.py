"""One step of K worlds × N agents (the rules are in SPEC.md beside this file)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from searchrl.world import kernels
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import MOVES, SUPPORT_DC, SUPPORT_DR, SUPPORT_G
from searchrl.world.seen import update_seen
from searchrl.world.state import WorldState


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


@lru_cache(maxsize=8)
def _scratch(side: int) -> tuple[np.ndarray, ...]:
    """Per-side scratch grids; every kernel leaves them as it found them (claim = -1, done = False)."""
    claim = np.full((side, side), -1, np.int32)
    surv = np.empty((side, side), np.float64)
    fsum = np.empty((side, side), np.float64)
    removed = np.empty((2, side, side), np.float64)
    done = np.zeros((side, side), np.bool_)
    return claim, surv, fsum, removed, done


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


def step(config: WorldConfig, state: WorldState, actions: np.ndarray, rng: np.random.Generator) -> StepResult:
    """Advance every world one step in place. actions: (K, N) ints in [0, config.n_actions)."""
    actions = check_actions(config, state, actions)
    k, n = actions.shape
    h = state.halo
    claim, surv, fsum, removed, done = _scratch(state.p.shape[1])
    priority = rng.random((k, n))  # tie-break for contested cells
    detect = rng.random(state.target_valid.shape)  # one uniform per target slot

    collided = np.empty((k, n), np.bool_)
    kernels.move_agents(state.pos, state.occupant, state.blocked, actions, priority, MOVES, h, claim, collided)

    targets_found = np.empty((k, n), np.int64)
    kernels.detect_targets(
        state.target_pos, state.target_valid, state.target_found, state.found_grid, state.n_found,
        state.occupant, detect, SUPPORT_DR, SUPPORT_DC, SUPPORT_G, h, targets_found,
    )  # fmt: skip

    info = np.empty((k, n), np.float64)
    kernels.sense(
        state.p, state.u, state.pos, SUPPORT_DR, SUPPORT_DC, SUPPORT_G, config.sensing_rate(state.size), h,
        surv, fsum, removed, done, info,
    )  # fmt: skip

    kernels.refresh_beliefs(
        state.belief, state.belief_box, state.belief_time, state.p, state.u, state.pos, state.t,
        config.explicit_area // 2, h,
    )  # fmt: skip

    if state.belief_seen.size:  # observation only: what each agent infers from the neighbours it sees
        update_seen(config, state, slice(None))

    comm_pairs = np.empty(k, np.int64)
    comm_gain = np.empty((k, n), np.float64)
    kernels.communicate(
        state.belief, state.belief_box, state.occupant, state.pos, config.comm_range // 2, h,
        config.communication, comm_pairs, comm_gain,
    )  # fmt: skip

    reward64 = (
        config.step_reward
        + config.collision_reward * collided
        + config.target_reward * targets_found
        + (config.xi / config.lam) * info
        + (config.tau / config.lam) * comm_gain
    )
    state.t += 1
    terminated = state.n_found == state.n_targets
    truncated = (state.t >= config.max_steps) & ~terminated
    state.ep_return += reward64.sum(axis=1)
    state.ep_info += info.sum(axis=1)
    state.ep_comm_pairs += comm_pairs
    state.ep_collisions += collided.sum(axis=1)
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
