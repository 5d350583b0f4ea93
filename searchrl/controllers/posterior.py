"""What the rollout planner imagines (searchrl/controllers/rollout.py): the unfound targets redrawn from the team's
posterior, the targets a path can expect to find under it, and the random numbers of a batch of imagined worlds.

The team's posterior: with λk = 1 sensing multiplies the probability map by exactly the chance it missed a target
there, so the map after every sensing so far is the prior given no detection, and a target lies in a free cell
without a found target with probability ∝ p(c)·(1 − u0(c)/max u0) (§4.1.4 keeps a target drawn from p with
probability 1 − u/max u of the prior's u, u0).
"""

from __future__ import annotations

import numpy as np

from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams
from searchrl.world.truth import place_targets

# WorldState's fields with an agent axis after the world axis: (K, N, ...)
PER_AGENT = ("belief", "belief_box", "belief_news", "merge_pos", "belief_time", "belief_seen", "pos")


def remember_prior_u(prior_u: np.ndarray, state: WorldState, mask: np.ndarray) -> np.ndarray:
    """prior_u (K, S, S) with the worlds of `mask` (K,) set to their u as reset drew it (§4.1.4 keeps a target by
    the prior's u, before any sensing); all worlds afresh when the batch's shape changed."""
    if prior_u.shape != state.u.shape:
        prior_u, mask = np.zeros(state.u.shape), np.ones(state.n_worlds, bool)
    prior_u[mask] = state.u[mask]
    return prior_u


def posterior_targets(
    p_now: np.ndarray, prior_u: np.ndarray, free: np.ndarray, count: int, samples: int, rng: np.random.Generator
) -> list[np.ndarray]:
    """`samples` draws of `count` targets' cells, (count, 2) int64 each, as a reset draws targets (§4.1.4: from p, kept
    with probability 1 − u/max u, distinct cells) from p_now (n, n), the prior p after every sensing so far (with
    lam·k = 1, the posterior given no detection), the prior's u (n, n), and `free` (n, n) bool: cells that may
    hold an unfound target (not blocked, no found target)."""
    p_now = np.asarray(p_now, np.float64)
    return [place_targets(p_now / p_now[free].sum(), prior_u, free, count, rng) for _ in range(samples)]


def expected_finds(state: WorldState, prior_u: np.ndarray, worlds: np.ndarray, p_end: np.ndarray) -> np.ndarray:
    """(G, m·C) the unfound targets' expected finds along each imagined path of real world worlds[g]; p_end
    (G·m·C, S, S) is its map at the path's end, in the imagined batch's order, prior_u (K, S, S) the real worlds'
    prior u. A target lies in cell c with the team's posterior q(c) ∝ p(c)·w(c) (p after all sensing so far,
    w = 1 − u0/max u0 on the free cells without a found target) and escapes the path's footprints with probability
    p_end(c)/p_start(c), so R unfound targets add R·Σ_c w(c)·(p_start − p_end)(c) / Σ_c w(c)·p_start(c). A rule
    that reads no find walks a path that does not depend on where the imagined targets lie: the score has no
    sampling noise but the rule's random moves and tie-breaks."""
    u0, p_start = prior_u[worlds], state.p[worlds]  # the weights once per real world, not per copy
    keep = 1.0 - u0 / np.maximum(u0.max(axis=(1, 2), keepdims=True), 1e-30)
    weight = np.where(state.blocked[worlds] | state.found_grid[worlds], 0.0, keep)  # (G, S, S)
    lost = (state.target_valid[worlds] & ~state.target_found[worlds]).sum(axis=1)
    mass = (weight * p_start).sum(axis=(1, 2), dtype=np.float64)
    ends = p_end.reshape(len(worlds), -1, *p_end.shape[1:])  # (G, m·C, S, S)
    swept = mass[:, None] - np.einsum("gxy,gjxy->gj", weight, ends)
    return lost[:, None] * swept / np.maximum(mass, 1e-30)[:, None]


class CommonStreams(WorldStreams):
    """The random numbers of an imagined batch laid out as world index (g·M + j)·C + c: group g (a real world), sample
    j, candidate c. Rows of sample j of group g come from group g's generator and are the same for every candidate
    (common random numbers); what a group draws does not depend on the groups beside it."""

    def __init__(self, keys: list[list[int]], samples: int, candidates: int) -> None:
        super().__init__(keys)
        self.samples, self.candidates = samples, candidates

    def __len__(self) -> int:
        return len(self.generators) * self.samples * self.candidates

    def _rows(self, size: int | tuple[int, ...]) -> tuple[int, ...]:
        size = (size,) if isinstance(size, (int, np.integer)) else tuple(size)
        if not size or size[0] != len(self):
            raise ValueError(
                f"a draw of size {size} from {len(self)} imagined worlds: its first axis must be {len(self)}"
            )
        return size[1:]

    def random(self, size: int | tuple[int, ...]) -> np.ndarray:
        rest = self._rows(size)
        draws = np.concatenate([g.random((self.samples, *rest)) for g in self.generators])
        return np.repeat(draws, self.candidates, axis=0)

    def integers(self, low: int, high: int, size: int | tuple[int, ...]) -> np.ndarray:
        rest = self._rows(size)
        draws = np.concatenate([g.integers(low, high, size=(self.samples, *rest)) for g in self.generators])
        return np.repeat(draws, self.candidates, axis=0)
