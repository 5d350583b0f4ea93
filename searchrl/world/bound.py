"""The per-map search bound: the most targets any team of N agents can expect to find in one episode of a map.

A target can only be found on a cell inside some agent's footprint support (Γ > 0, 13 cells) during a detection
phase (phase 2 of every step; a reset detects nothing). Over T steps one agent's footprints cover at most
13 + new·(T - 1) cells, `new` the most cells one move adds to the support (5 for every cardinal and diagonal move;
`new_cells_per_move` counts them). So a team covers at most K = N·(13 + new·(T - 1)) cells, and whatever it does,
the expected number of targets it finds is at most the expected number of targets on the K cells most likely to
hold one: the sum of the K largest target marginals π(c) = P(a target is on c).

The marginals are those of the placement of §4.1.4 (`reset.place_targets`): a cell drawn ∝ p and kept with
probability 1 - u/max(u), redrawn while taken, until j distinct cells hold targets. That is successive sampling
without replacement with weights w = p·(1 - u/max u) over the free cells, which the Gumbel-top-j trick reproduces
exactly (the j largest of log w + Gumbel noise), so π is estimated from `draws` independent placements at once.

The bound ignores geometry (the K cells need not be reachable as N paths) and takes detection as certain on every
covered cell, so it is loose where the best mass is scattered or one pass misses targets; it is an upper bound,
not a target. Shapes: maps (n, n); marginals (n, n) float64.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from searchrl.world.footprint import MOVES, SUPPORT, Footprint
from searchrl.world.reset import keep_probability


class SearchBound(NamedTuple):
    expected: float  # the bound on expected targets found, sum of the `reach` largest estimated marginals
    stderr: float  # its Monte Carlo standard error over the draws
    reach: int  # K, the most cells the team's footprints can cover
    draws: int


def new_cells_per_move(support: Footprint = SUPPORT, moves: np.ndarray = MOVES) -> int:
    """The most cells any non-stay move adds to the footprint support (5 for Γ's 13-cell disc, every move)."""
    cells = set(zip(support.dr.tolist(), support.dc.tolist(), strict=True))
    added = [len({(r + dr, c + dc) for r, c in cells} - cells) for dr, dc in moves.tolist() if (dr, dc) != (0, 0)]
    return max(added)


def team_reach(n_agents: int, steps: int, n_actions: int = 5, support: Footprint = SUPPORT) -> int:
    """K = N·(|support| + new·(steps - 1)): the most cells N agents' footprints cover in `steps` detection phases."""
    new = new_cells_per_move(support, MOVES[:n_actions])
    return n_agents * (len(support.dr) + new * (steps - 1))


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
    log_w = np.where(flat > 0, np.log(np.where(flat > 0, flat, 1.0)), -np.inf)
    if np.isfinite(log_w).sum() < count:
        raise ValueError(f"count={count} targets need as many cells of positive weight ({np.isfinite(log_w).sum()})")
    chosen = np.empty((draws, count), np.int64)
    for start in range(0, draws, chunk):
        keys = log_w + rng.gumbel(size=(min(chunk, draws - start), flat.size))
        chosen[start : start + len(keys)] = np.argpartition(-keys, count - 1, axis=1)[:, :count]
    hits = np.bincount(chosen.ravel(), minlength=flat.size).astype(np.float64)
    return (hits / draws).reshape(weights.shape), chosen


def search_bound(
    p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, reach: int, draws: int, rng: np.random.Generator
) -> SearchBound:
    """The bound for one map: the expected targets on the `reach` cells of largest estimated marginal.

    Choosing the cells and scoring them on the same draws biases the estimate up, never down (the best of noisy
    sums), so it stays an upper bound in expectation; `stderr` is the spread of the per-draw counts on those cells.
    """
    marginals, chosen = target_marginals(placement_weights(p, u, free), count, draws, rng)
    flat = marginals.ravel()
    k = min(int(reach), int(free.sum()))
    best = np.zeros(flat.size, bool)
    best[np.argpartition(-flat, k - 1)[:k]] = True
    per_draw = best[chosen].sum(axis=1)
    return SearchBound(float(per_draw.mean()), float(per_draw.std(ddof=1) / np.sqrt(draws)), k, draws)
