"""The per-map search bound: the most targets any team of N agents can expect to find in one episode of a map.

A target can only be found on a cell inside some agent's footprint support (Γ > 0, 13 cells) during a detection
phase (phase 2 of every step; a reset detects nothing). Over T steps one agent's footprints cover at most
13 + new·(T - 1) cells, `new` the most cells one move adds to the support (5 for every cardinal and diagonal move;
`new_cells_per_move` counts them). So a team covers at most K = N·(13 + new·(T - 1)) cells, and whatever it does,
the expected number of targets it finds is at most the expected number of targets on the K cells most likely to
hold one: the sum of the K largest target marginals π(c) = P(a target is on c).

The marginals are those of the placement of §4.1.4 (`scenario.place_targets`): a cell drawn ∝ p and kept with
probability 1 - u/max(u), redrawn while taken, until j distinct cells hold targets. That is successive sampling
without replacement with weights w = p·(1 - u/max u) over the free cells, which the Gumbel-top-j trick reproduces
exactly (the j largest of log w + Gumbel noise), so π is estimated from `draws` independent placements at once.

The bound ignores geometry (the K cells need not be reachable as N paths) and takes detection as certain on every
covered cell, so it is loose where the best mass is scattered or one pass misses targets; it is an upper bound,
not a target. Shapes: maps (n, n); marginals (n, n) float64.

The detection bound, tighter, counts detection probability instead of cells. A target on c is found by step T with
probability P_T(c) = 1 - Π over phases and agents of (1 - Γ(c - position)) (independent draws each phase), so
one agent's phase raises P(c) by at most Γ(c - p')·(1 - P(c)) ≤ Γ(c - p')·(1 - Γ(c - p)): that agent sensed c
from its previous cell p in the phase before, with probability Γ(c - p). Summed over c, a phase adds at most
D = max over moves of Σ_c Γ(c - p - m)·(1 - Γ(c - p)) (3.17 for a cardinal move, 3.77 diagonal; staying 2.35)
and the first phase at most ΣΓ = 5.44; several agents' phases add at most the sum of theirs. So Σ_c P_T(c) ≤
B = N·(ΣΓ + D·(T - 1)) on every trajectory, and the expected targets found, Σ_c π(c)·P_T(c) with 0 ≤ P ≤ 1, is at
most the mass of the ⌊B⌋ cells of largest π plus the fraction B - ⌊B⌋ of the next: the cell bound with B in
place of K (about 0.63 K). Until a target is found the team's path does not depend on where it lies, so the
argument holds for adaptive teams as the cell bound does.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from searchrl.world.footprint import GAMMA, MOVES, SUPPORT, Footprint
from searchrl.world.libm import log
from searchrl.world.truth import keep_probability


class SearchBound(NamedTuple):
    expected: float  # the bound on expected targets found, sum of the `reach` largest estimated marginals
    stderr: float  # its Monte Carlo standard error over the draws
    reach: int  # K, the most cells the team's footprints can cover
    draws: int
    detection: tuple[float, ...] = ()  # the detection bound per budget: its ⌊budget⌋ largest marginals, one in part
    detection_stderr: tuple[float, ...] = ()


def new_cells_per_move(support: Footprint = SUPPORT, moves: np.ndarray = MOVES) -> int:
    """The most cells any non-stay move adds to the footprint support (5 for Γ's 13-cell disc, every move)."""
    cells = set(zip(support.dr.tolist(), support.dc.tolist(), strict=True))
    added = [len({(r + dr, c + dc) for r, c in cells} - cells) for dr, dc in moves.tolist() if (dr, dc) != (0, 0)]
    return max(added)


def team_reach(n_agents: int, steps: int, n_actions: int = 5, support: Footprint = SUPPORT) -> int:
    """K = N·(|support| + new·(steps - 1)): the most cells N agents' footprints cover in `steps` detection phases."""
    new = new_cells_per_move(support, MOVES[:n_actions])
    return n_agents * (len(support.dr) + new * (steps - 1))


def detection_per_move(gamma: np.ndarray = GAMMA, moves: np.ndarray = MOVES) -> float:
    """D: the most detection probability one phase can add over all cells, max over `moves` (staying included)
    of Σ_c Γ(c - p - m)·(1 - Γ(c - p)), given that the agent sensed from p in the phase before."""
    r = gamma.shape[0] // 2
    pad = np.zeros((gamma.shape[0] + 2, gamma.shape[1] + 2))
    pad[1:-1, 1:-1] = gamma  # the footprint at p, with room for one move
    added = []
    for dr, dc in moves.tolist():
        moved = np.zeros_like(pad)
        moved[1 + dr : 1 + dr + 2 * r + 1, 1 + dc : 1 + dc + 2 * r + 1] = gamma
        added.append(float((moved * (1.0 - pad)).sum()))
    return max(added)


def detection_budget(n_agents: int, steps: int, n_actions: int = 5, gamma: np.ndarray = GAMMA) -> float:
    """B = N·(ΣΓ + D·(steps - 1)): the most detection probability, summed over cells, that N agents can gather in
    `steps` detection phases (the module docstring proves it)."""
    return n_agents * (float(gamma.sum()) + detection_per_move(gamma, MOVES[:n_actions]) * (steps - 1))


def placement_weights(p: np.ndarray, u: np.ndarray, free: np.ndarray) -> np.ndarray:
    """w (n, n) float64 of `place_targets`: p times its keep probability, zero off the free cells."""
    return np.where(free, p * keep_probability(u), 0.0)


def target_marginals(
    weights: np.ndarray, count: int, draws: int, rng: np.random.Generator, chunk: int = 64
) -> tuple[np.ndarray, np.ndarray]:
    """(π̂ (n, n) float64, chosen (draws, count) int64 flat cells): `draws` placements of `count` targets by
    successive sampling with `weights`, each the `count` largest of log w + Gumbel noise, and the fraction of
    draws that put a target on each cell. π̂ sums to `count`."""
    flat = weights.ravel()
    log_w = np.where(flat > 0, log(np.where(flat > 0, flat, 1.0)), -np.inf)  # libm.py: why not numpy's
    if np.isfinite(log_w).sum() < count:
        raise ValueError(f"count={count} targets need as many cells of positive weight ({np.isfinite(log_w).sum()})")
    chosen = np.empty((draws, count), np.int64)
    for start in range(0, draws, chunk):
        keys = log_w + rng.gumbel(size=(min(chunk, draws - start), flat.size))
        chosen[start : start + len(keys)] = np.argpartition(-keys, count - 1, axis=1)[:, :count]
    hits = np.bincount(chosen.ravel(), minlength=flat.size).astype(np.float64)
    return (hits / draws).reshape(weights.shape), chosen


def _top_mass(flat: np.ndarray, chosen: np.ndarray, amount: float) -> tuple[float, float]:
    """(mean, standard error) over the draws `chosen` (draws, count) of the targets on the ⌊amount⌋ cells of
    largest marginal in `flat`, plus the fraction amount - ⌊amount⌋ of those on the next cell."""
    amount = min(float(amount), float((flat > 0).sum()))
    whole = int(amount)
    order = np.argsort(-flat, kind="stable")
    share = np.zeros(flat.size)
    share[order[:whole]] = 1.0
    if whole < flat.size:
        share[order[whole]] = amount - whole
    per_draw = share[chosen].sum(axis=1)
    return float(per_draw.mean()), float(per_draw.std(ddof=1) / np.sqrt(len(chosen)))


def search_bound(
    p: np.ndarray,
    u: np.ndarray,
    free: np.ndarray,
    count: int,
    reach: int,
    draws: int,
    rng: np.random.Generator,
    budgets: Sequence[float] = (),
) -> SearchBound:
    """The bound for one map: the expected targets on the `reach` cells of largest estimated marginal, and for each
    of `budgets` (`detection_budget`, one per move set say) the detection bound on the same draws.

    Choosing the cells and scoring them on the same draws biases the estimate up, never down (the best of noisy
    sums), so it stays an upper bound in expectation; `stderr` is the spread of the per-draw counts on those cells.
    """
    marginals, chosen = target_marginals(placement_weights(p, u, free), count, draws, rng)
    flat = np.where(free.ravel(), marginals.ravel(), 0.0)
    k = min(int(reach), int(free.sum()))
    expected, stderr = _top_mass(flat, chosen, k)
    detection = [_top_mass(flat, chosen, budget) for budget in budgets]
    return SearchBound(expected, stderr, k, draws, tuple(d[0] for d in detection), tuple(d[1] for d in detection))
