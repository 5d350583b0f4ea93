"""The per-map search bound (searchrl/world/bound.py): exact marginals on a tiny map, the same law as the world's
placement, the team's reach, and that a controller's finds stay under it."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from searchrl.world.bound import (
    new_cells_per_move,
    placement_weights,
    search_bound,
    target_marginals,
    team_reach,
)
from searchrl.world.footprint import MOVES
from searchrl.world.reset import place_targets


def _tiny_map(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    p, u = rng.random((3, 3)), rng.random((3, 3))
    free = np.ones((3, 3), bool)
    free[1, 1] = False  # an obstacle carries no target
    return p / p.sum(), u / u.sum(), free


def _exact_marginals(weights: np.ndarray, count: int) -> np.ndarray:
    """Inclusion probabilities of successive sampling, by enumerating every ordered draw."""
    w = weights.ravel()
    exact = np.zeros(w.size)
    for order in itertools.permutations(np.flatnonzero(w > 0).tolist(), count):
        prob, left = 1.0, w.sum()
        for cell in order:
            prob *= w[cell] / left
            left -= w[cell]
        exact[list(order)] += prob
    return exact.reshape(weights.shape)


def test_marginals_are_those_of_successive_sampling():
    p, u, free = _tiny_map()
    weights = placement_weights(p, u, free)
    exact = _exact_marginals(weights, 3)
    estimate, chosen = target_marginals(weights, 3, 40_000, np.random.default_rng(1))
    assert estimate.sum() == pytest.approx(3) and estimate[1, 1] == 0 and chosen.shape == (40_000, 3)
    stderr = np.sqrt(exact * (1 - exact) / 40_000)
    assert (np.abs(estimate - exact) <= 4 * stderr + 1e-12).all()


def test_the_worlds_placement_has_the_same_marginals():
    p, u, free = _tiny_map(2)
    exact = _exact_marginals(placement_weights(p, u, free), 2)
    rng, draws = np.random.default_rng(3), 6000
    counts = np.zeros((3, 3))
    for _ in range(draws):
        targets = place_targets(p, u, free, 2, rng)
        counts[targets[:, 0], targets[:, 1]] += 1
    stderr = np.sqrt(exact * (1 - exact) / draws)
    assert (np.abs(counts / draws - exact) <= 4 * stderr + 1e-12).all()


def test_a_team_covers_at_most_13_plus_5_cells_per_move_per_agent():
    assert new_cells_per_move(moves=MOVES[:5]) == 5 and new_cells_per_move(moves=MOVES) == 5  # diagonal: 5 too
    assert team_reach(1, 1) == 13 and team_reach(8, 256) == 8 * (13 + 5 * 255) == team_reach(8, 256, n_actions=9)


def test_the_bound_grows_with_reach_and_saturates_at_the_target_count():
    p, u, free = _tiny_map(4)
    bounds = [search_bound(p, u, free, 3, k, 2000, np.random.default_rng(5)).expected for k in range(1, 9)]
    assert all(a <= b for a, b in itertools.pairwise(bounds)) and bounds[-1] == pytest.approx(3)
    assert bounds[2] < 3  # three cells do not hold all three targets every time
