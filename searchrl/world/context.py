"""Whole-belief context (issue 29; not in the paper, whose §7 proposes it): an optional observation part that shows
each agent its own belief over the entire world at a fixed resolution, so that a policy can head for mass beyond
its field of view and notice ground that is already cleared.

With `WorldConfig.context` = G > 0, agent i of world k sees a (3, G, G) float32 image of its own world:
  0  its belief p, averaged over each of G × G bins, times the world's observation scale (1 / max of the prior p),
  1  its belief u, likewise (1 / max of the prior u),
  2  the share of each bin's cells inside its field of view (where it stands, and what its view already shows).
Bins split the world's side n into G nearly equal runs (row r falls in bin ⌊r·G/n⌋; n >= G, so none is empty), so
every world size fills the whole image. It uses only what the agent knows: its own belief (merged with its
neighbours' in model B, as the field of view's belief channels are) and its own position. Off (G = 0) nothing is
computed or allocated, and the paper's observation is unchanged.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from searchrl.world.config import WorldConfig
from searchrl.world.kernels import _CACHE
from searchrl.world.state import WorldState

CONTEXT_CHANNELS = 3  # pooled belief p, pooled belief u, the field of view's share of each bin


def context_buffer(config: WorldConfig, n_worlds: int) -> np.ndarray | None:
    """An empty (K, N, 3, G, G) float32 buffer for `observe_context`, or None when the context is off."""
    if not config.context:
        return None
    return np.empty((n_worlds, config.n_agents, CONTEXT_CHANNELS, config.context, config.context), np.float32)


def observe_context(config: WorldConfig, state: WorldState, out: np.ndarray | None = None) -> np.ndarray | None:
    """Every agent's context (K, N, 3, G, G) float32 in [0, 1], or None when `config.context` is 0. Pass `out`
    (`context_buffer`) to reuse a buffer."""
    if not config.context:
        return None
    out = context_buffer(config, state.n_worlds) if out is None else out
    context_into(state.belief, state.obs_scale, state.pos, state.size, state.halo, config.fov, out)
    return out


@njit(cache=_CACHE)
def context_into(belief, obs_scale, pos, size, halo, fov, out):
    """out (K, N, 3, G, G) <- the pooled beliefs and field-of-view shares of every agent (module docstring).
    belief (K, N, 2, S, S) float32 padded by `halo`; obs_scale (K, 2); pos (K, N, 2) unpadded; size (K,)."""
    n_worlds, n_agents, grid = out.shape[0], out.shape[1], out.shape[3]
    half = fov // 2
    acc = np.empty((2, grid, grid), np.float64)  # scratch reused by every agent: no allocation per agent
    view = np.empty((grid, grid), np.float64)
    for k in range(n_worlds):
        n = size[k]
        bin_of = np.empty(n, np.int64)  # the bin of each row (and column): ⌊r·G/n⌋
        count = np.zeros(grid, np.float64)
        for r in range(n):
            bin_of[r] = r * grid // n
            count[bin_of[r]] += 1.0
        sp, su = obs_scale[k, 0], obs_scale[k, 1]
        for i in range(n_agents):
            acc[:] = 0.0
            bel_p, bel_u = belief[k, i, 0], belief[k, i, 1]
            for r in range(n):
                br = bin_of[r]
                for c in range(n):
                    acc[0, br, bin_of[c]] += bel_p[r + halo, c + halo]
                    acc[1, br, bin_of[c]] += bel_u[r + halo, c + halo]
            view[:] = 0.0
            r_lo, r_hi = max(pos[k, i, 0] - half, 0), min(pos[k, i, 0] + half, n - 1)
            c_lo, c_hi = max(pos[k, i, 1] - half, 0), min(pos[k, i, 1] + half, n - 1)
            for r in range(r_lo, r_hi + 1):
                for c in range(c_lo, c_hi + 1):
                    view[bin_of[r], bin_of[c]] += 1.0
            for a in range(grid):
                for b in range(grid):
                    cells = count[a] * count[b]
                    out[k, i, 0, a, b] = min(acc[0, a, b] / cells * sp, 1.0)
                    out[k, i, 1, a, b] = min(acc[1, a, b] / cells * su, 1.0)
                    out[k, i, 2, a, b] = view[a, b] / cells
