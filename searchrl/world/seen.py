"""What an agent can infer from the neighbours it sees (`WorldConfig.belief_seen`, observation only).

A neighbour in an agent's field of view has just sensed its footprint, and sensing scales p and u of each cell
there by (1 − Γ) (eq. 1 with λk = 1). Without merging (model C) an agent's belief never hears of it; this keeps,
per agent and cell, the product of those factors over the neighbours it has seen since it last saw the cell's
truth in Φ, which the observation multiplies into the belief's freshness. It is what footprint-greedy's `seen`
keeps (searchrl/controllers/greedy.py), computed the same way, so a policy sees what that teacher scores.
"""

from __future__ import annotations

from numba import njit

from searchrl.world.config import WorldConfig
from searchrl.world.footprint import SUPPORT_DC, SUPPORT_DR, SUPPORT_G
from searchrl.world.kernels import _CACHE
from searchrl.world.state import WorldState


def update_seen(config: WorldConfig, state: WorldState, worlds: slice) -> None:
    """Apply `see_neighbours` to state.belief_seen of `worlds` (all of them after a step, one after its reset)."""
    see_neighbours(
        state.belief_seen[worlds], state.occupant[worlds], state.pos[worlds], SUPPORT_DR, SUPPORT_DC, SUPPORT_G,
        config.fov // 2, config.explicit_area // 2, state.halo,
    )  # fmt: skip


@njit(cache=_CACHE)
def see_neighbours(belief_seen, occupant, pos, dr, dc, g, view, phi, h):
    """belief_seen (K,N,S,S) float32 *= (1 − Γ) under the footprint of every other agent within Chebyshev
    distance `view` of each agent (scanned row by row, as greedy does), then = 1 on the agent's own Φ (radius
    `phi`), where its belief is the truth. occupant (K,S,S) int32 and pos (K,N,2) int64 are the new positions;
    (dr, dc, g) is Γ's support."""
    n_worlds, n_agents = pos.shape[0], pos.shape[1]
    for k in range(n_worlds):
        occ = occupant[k]
        for i in range(n_agents):
            seen = belief_seen[k, i]
            r0, c0 = pos[k, i, 0] + h, pos[k, i, 1] + h
            for r in range(r0 - view, r0 + view + 1):
                for c in range(c0 - view, c0 + view + 1):
                    j = occ[r, c]
                    if j >= 0 and j != i:
                        for s in range(g.shape[0]):
                            seen[r + dr[s], c + dc[s]] *= 1.0 - g[s]
            for r in range(r0 - phi, r0 + phi + 1):
                for c in range(c0 - phi, c0 + phi + 1):
                    seen[r, c] = 1.0
