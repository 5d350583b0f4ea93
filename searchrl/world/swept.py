"""Swept cells: the cells the team's footprints have covered since the reset, and the agent-steps that covered no
new one (SPEC.md step 3, *Swept*). A measure of search, not of the agents' knowledge: no observation shows it and
no reward uses it. An evaluation row's `stale` is the share of its agent-steps that swept nothing new, how often a
rule walks over ground the team has already covered (back and forth in a pocket it cleared, say)."""

from __future__ import annotations

from numba import njit

from searchrl.world.kernels import CACHE


@njit(cache=CACHE)
def sweep(w, first, stop, support, stale):
    """In worlds first..stop-1: stale (K,N) bool True where no free cell under agent i's footprint (Γ > 0; support:
    a `Footprint`) was unswept before this step, every agent judged against the same map; then every footprint's
    cells are marked in w.swept (K,S,S) bool. Positions are the new ones (after the move)."""
    pos, swept, blocked, h = w.pos, w.swept, w.blocked, w.halo
    dr, dc = support.dr, support.dc
    for k in range(first, stop):
        for i in range(pos.shape[1]):
            r0, c0 = pos[k, i, 0] + h, pos[k, i, 1] + h
            new = False
            for s in range(dr.shape[0]):
                if not swept[k, r0 + dr[s], c0 + dc[s]] and not blocked[k, r0 + dr[s], c0 + dc[s]]:
                    new = True
                    break
            stale[k, i] = not new
        for i in range(pos.shape[1]):
            r0, c0 = pos[k, i, 0] + h, pos[k, i, 1] + h
            for s in range(dr.shape[0]):
                swept[k, r0 + dr[s], c0 + dc[s]] = True
