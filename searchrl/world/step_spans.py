"""The step over a span of worlds (`step.step_worlds` gives each thread one), and over worlds whose merges are shared
among the threads when there are fewer worlds than threads. SPEC.md's phases in order; each reads and writes the rows
of its own worlds only (kernels.py)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange, types
from numba.experimental import structref

from searchrl.world import kernels
from searchrl.world.kernels import CACHE
from searchrl.world.merge import communicate, merge_values, plan_merge, write_merge
from searchrl.world.parallel import block_span
from searchrl.world.sums import numpy_sum
from searchrl.world.swept import sweep

# The fewest agents of a block of a shared merge. A shared step opens three parallel regions where a world's own
# thread opens none, so a small team (whose merge is a few microseconds) stays whole.
MERGE_BLOCK_AGENTS = 16


@structref.register
class StepInputsType(types.StructRef):
    """The numba type of `StepInputs`."""

    def preprocess_fields(self, fields: tuple) -> tuple:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class StepInputs(structref.StructRefProxy):
    """What every phase of a step reads besides the world, as one object (`step.step_worlds` makes it; kernels read
    it, one pointer however many they pass it on to): actions (K,N) int64, priority (K,N) and detect (K,T) float64
    the step's draws, moves (A,2) int64, support a `Footprint`, c_coef (K,) float64 each world's λk, radii (2,)
    int64 those of Φ and of communication, merge whether beliefs merge, reward_terms (5,) float64 and max_steps."""


_INPUTS = ("actions", "priority", "detect", "moves", "support", "c_coef", "radii", "merge", "reward_terms", "max_steps")
structref.define_proxy(StepInputs, StepInputsType, _INPUTS)


@njit(cache=CACHE)
def _act_and_sense(w, s, scratch, out, slot, first, stop):
    """Phases 1-4 of SPEC.md's step for worlds first..stop-1 (`s` the step's `StepInputs`), with scratch slot
    `slot`."""
    collided, found_by, collected, stale = out[:4]
    actions, support, c_coef = s.actions, s.support, s.c_coef
    n_agents, n_support = actions.shape[1], support.dr.shape[0]
    target, candidate = np.empty((n_agents, 2), np.int64), np.empty(n_agents, np.bool_)
    cover_agent, cover_g = np.empty(n_support, np.int64), np.empty(n_support, np.float64)
    claim, surv, fsum = scratch.claim[slot], scratch.surv[slot], scratch.fsum[slot]
    removed, done = scratch.removed[slot], scratch.done[slot]
    kernels.move_agents(w, first, stop, actions, s.priority, s.moves, claim, target, candidate, collided)
    kernels.detect_targets(w, first, stop, s.detect, support, cover_agent, cover_g, found_by)
    kernels.sense(w, first, stop, support, c_coef, surv, fsum, removed, done, collected)
    sweep(w, first, stop, support, stale)
    kernels.refresh_beliefs(w, first, stop, s.radii[0])


@njit(cache=CACHE)
def step_span(w, s, scratch, work, out, slot, first, stop):
    """`step_worlds` for worlds first..stop-1 (`s` the step's `StepInputs`), with scratch and work slot `slot`."""
    n_agents = s.actions.shape[1]
    _act_and_sense(w, s, scratch, out, slot, first, stop)
    communicate(w, first, stop, s.radii[1], s.merge, work, slot, out[4], out[5])
    _account(w, first, stop, s.reward_terms, s.max_steps, out, np.empty(n_agents), np.empty(n_agents))


@njit(cache=CACHE)
def _prepare_merge(w, s, scratch, work, out, k):
    """World k's phases 1-4 and its merge's plan, in scratch and work slot k; returns its merge's buffer length."""
    _act_and_sense(w, s, scratch, out, k, k, k + 1)
    return plan_merge(w, k, s.radii[1], np.bool_(True), work, k, out[4], out[5])


@njit(cache=CACHE, parallel=True)
def step_sharing_merges(w, s, scratch, work, out, blocks):
    """`step_worlds` with merges (K < threads): world k's phases 1-4 and its merge's plan on a thread of its own
    (scratch and work slot k), then its merge's two passes shared among the threads, `blocks` blocks of agents a
    world (each pass reads what the one before wrote, so each is a parallel region of its own), then phases 6-7
    in this thread. Each agent's values, ΔM and box are computed as in `communicate`, so the step is the same bit
    for bit."""
    comm_gain = out[5]
    n_worlds, n_agents = s.actions.shape
    size = np.empty(n_worlds, np.int64)
    if n_worlds == 1:  # in this thread: a parallel region of one world would only wake the others
        size[0] = _prepare_merge(w, s, scratch, work, out, np.int64(0))
    else:
        for k in prange(n_worlds):
            size[k] = _prepare_merge(w, s, scratch, work, out, np.int64(k))
    base = np.zeros(n_worlds + 1, np.int64)
    for k in range(n_worlds):
        base[k + 1] = base[k] + size[k]
    buf = np.empty(base[n_worlds], np.float32)
    for job in prange(n_worlds * blocks):
        k, first, stop = block_span(job, blocks, n_agents)
        merge_values(w, k, first, stop, work, k, buf, base[k])
    for job in prange(n_worlds * blocks):
        k, first, stop = block_span(job, blocks, n_agents)
        write_merge(w, k, first, stop, work, k, buf, base[k], comm_gain)
    _account(w, np.int64(0), n_worlds, s.reward_terms, s.max_steps, out, np.empty(n_agents), np.empty(n_agents))


@njit(cache=CACHE)
def _account(w, first, stop, reward_terms, max_steps, out, reward64, info64):
    """Phases 6 and 7 of SPEC.md for worlds first..stop-1: each agent's reward into out's reward (float32), the
    clock and the episode's end into out's terminated and truncated, and the episode's tallies. reward64 and info64
    (N,) float64 are work space. The terms are added in SPEC.md's order and the team's sums are numpy's
    (`numpy_sum`), so the figures are those of the same sums in numpy, bit for bit."""
    collided, found_by, collected, stale, comm_pairs, comm_gain, reward, terminated, truncated = out
    step_reward, collision_reward, target_reward, info_weight, comm_weight = reward_terms
    t, n_found, n_targets = w.t, w.n_found, w.n_targets  # fields read once (kernels.py: no view in the loops)
    ep_return, ep_info, ep_comm_pairs, ep_collisions, ep_stale = (
        w.ep_return,
        w.ep_info,
        w.ep_comm_pairs,
        w.ep_collisions,
        w.ep_stale,
    )
    n_agents = reward64.shape[0]
    for k in range(first, stop):
        n_collided = n_stale = 0
        for i in range(n_agents):
            reward64[i] = (
                step_reward
                + collision_reward * collided[k, i]
                + target_reward * found_by[k, i]
                + info_weight * collected[k, i]
                + comm_weight * comm_gain[k, i]
            )
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
