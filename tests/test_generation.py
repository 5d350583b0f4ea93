"""World generation (§4.1): maps, targets, start positions, per-world reset and seeding."""

from __future__ import annotations

import math

import numpy as np
import pytest

from searchrl.world.config import WorldConfig
from searchrl.world.maps import gaussian_components, probability_map, uncertainty_map
from searchrl.world.reset import reset_worlds
from searchrl.world.scenario import IidObstacles, Scenario
from searchrl.world.state import allocate
from searchrl.world.truth import place_targets


def _inner(state, k):
    h, n = state.halo, int(state.size[k])
    return (k, slice(h, h + n), slice(h, h + n))


def test_maps_follow_eq_7_and_8():
    rng = np.random.default_rng(0)
    mix = gaussian_components(30, 20, 300.0, 1.0, 0.8, rng).sum(axis=0)
    p, u = probability_map(mix, eta=0.1), uncertainty_map(mix)
    assert p.shape == (30, 30)
    assert p.sum() == pytest.approx(1.0) and u.sum() == pytest.approx(1.0)
    assert p.min() >= 0.1 / 900 - 1e-15  # the η baseline: every cell keeps η / n²
    assert u.min() >= 0.0


# The C library's exp, element by element: numpy's own np.exp runs AVX-512 code where the CPU has it, which differs
# from the C library's in the last bit for a few inputs in a thousand (searchrl/world/libm.py).
_exp = np.vectorize(math.exp, otypes=[np.float64])


def _numpy_components(n, m, variance_high, variance_low, rho_max, rng):
    """Eq. 6's m densities in plain numpy broadcasts with the C library's exp, the formula `gaussian_components`
    works in compiled code."""
    mu = rng.uniform(0.0, n - 1.0, size=(m, 2))
    var = rng.uniform(variance_low, variance_high, size=(m, 2))
    rho = rng.uniform(-rho_max, rho_max, size=m)
    sx, sy = np.sqrt(var[:, 0]), np.sqrt(var[:, 1])
    coords = np.arange(n, dtype=np.float64)
    dx = ((coords[None, :] - mu[:, 0:1]) / sx[:, None])[:, None, :]
    dy = ((coords[None, :] - mu[:, 1:2]) / sy[:, None])[:, :, None]
    one_minus = (1.0 - rho**2)[:, None, None]
    quad = dx**2 + dy**2 - 2.0 * rho[:, None, None] * dx * dy
    return _exp(quad / -(2.0 * one_minus)) / (2.0 * np.pi * sx * sy * np.sqrt(one_minus[:, 0, 0]))[:, None, None]


@pytest.mark.parametrize("n, m", [(1, 1), (7, 3), (40, 16), (83, 5)])
def test_gaussian_components_are_the_formula_in_numpy_bit_for_bit(n, m):
    """The compiled exponent changes no bit of the maps, so no world drawn before it changes."""
    for seed in range(5):
        got = gaussian_components(n, m, 10.0 * n, 1.0, 0.8, np.random.default_rng(seed))
        want = _numpy_components(n, m, 10.0 * n, 1.0, 0.8, np.random.default_rng(seed))
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))


def test_gaussian_densities_are_the_same_bits_in_any_number_of_chunks():
    """The maps' kernel cuts its rows among threads; no cut changes a bit (one chunk runs without a region)."""
    from searchrl.world.maps import Gaussians, _densities

    gaussians = Gaussians.draw(37, 5, 370.0, 1.0, 0.8, np.random.default_rng(3))
    want = _numpy_components(37, 5, 370.0, 1.0, 0.8, np.random.default_rng(3))
    for threads in (1, 2, 3, 7):
        got = np.empty((5, 37, 37))
        _densities(gaussians.mu, gaussians.var, gaussians.rho, got, threads)
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))


@pytest.mark.parametrize("n, m", [(1, 1), (7, 3), (40, 16), (160, 8)])
def test_mixture_maps_are_eq_7_and_8_in_numpy_bit_for_bit(n, m):
    """p and u in one compiled pass (the mixtures, their pairwise totals, eq. 7 and 8) keep numpy's bits in any
    number of chunks, so no world drawn before it changes."""
    from searchrl.world.maps import Gaussians, _mixture_maps

    rng = np.random.default_rng(n)
    both = Gaussians.draw(n, m, 10.0 * n, 1.0, 0.8, rng) + Gaussians.draw(n, m, 2.0 * n, 1.0, 0.8, rng)
    densities = both.densities(n)
    want_p, want_u = probability_map(densities[:m].sum(axis=0), 0.1), uncertainty_map(densities[m:].sum(axis=0))
    for threads in (1, 2, 3, 7):
        p, u = np.empty((n, n)), np.empty((n, n))
        _mixture_maps(densities, m, 0.1, p, u, threads)
        np.testing.assert_array_equal(p.view(np.int64), want_p.view(np.int64))
        np.testing.assert_array_equal(u.view(np.int64), want_u.view(np.int64))


def _numpy_placement(p, u, free, count, rng):
    """§4.1.4's placement in plain numpy, the law `place_targets` works in compiled batches."""
    n, cdf = p.shape[0], np.cumsum(np.where(free, p, 0.0).ravel())
    keep_prob, chosen = (1.0 - u / u.max()).ravel(), []
    while True:
        cells = np.minimum(np.searchsorted(cdf, rng.random(4 * count) * cdf[-1], side="right"), n * n - 1)
        for cell in cells[rng.random(4 * count) < keep_prob[cells]].tolist():
            if cell not in chosen:
                chosen.append(cell)
                if len(chosen) == count:
                    return np.stack(np.divmod(np.array(chosen, np.int64), n), axis=1)


@pytest.mark.parametrize("obstacles", [False, True])
def test_place_targets_is_the_law_in_numpy_draw_for_draw(obstacles):
    """The compiled batches choose the same cells from the same uniforms and leave the generator where numpy's
    loop leaves it."""
    maps = np.random.default_rng(11)
    for trial in range(40):
        n = int(maps.integers(2, 50))
        p, u = maps.random((n, n)) ** 3, maps.random((n, n))  # a cell is kept with probability 1 - u / max u
        free = maps.random((n, n)) > 0.3 if obstacles else np.ones((n, n), bool)
        free.flat[:2] = True  # room for a target
        count = int(maps.integers(1, min(10, free.sum() // 2) + 1))
        got_rng, want_rng = np.random.default_rng(trial), np.random.default_rng(trial)
        got = place_targets(p / p.sum(), u / u.sum(), free, count, got_rng)
        np.testing.assert_array_equal(got, _numpy_placement(p / p.sum(), u / u.sum(), free, count, want_rng))
        assert got.dtype == np.int64 and got_rng.random() == want_rng.random()


def test_reset_writes_a_consistent_world():
    config = WorldConfig(world_size=(20, 40), n_targets=(8, 16), n_agents=8)
    state = allocate(config, 6)
    reset_worlds(config, state, np.ones(6, bool), np.random.default_rng(1))
    for k in range(6):
        n, h = int(state.size[k]), state.halo
        assert 20 <= n <= 40 and 8 <= state.n_targets[k] <= 16
        assert state.p[_inner(state, k)].sum() == pytest.approx(1.0, rel=1e-5)
        assert state.p[k].sum() == pytest.approx(1.0, rel=1e-5)  # nothing outside the world
        assert state.blocked[k].sum() == state.blocked[k].size - n * n  # no obstacles at density 0
        tp = state.target_pos[k, : state.n_targets[k]]
        assert len({tuple(t) for t in tp}) == len(tp)  # distinct target cells
        assert ((tp >= 0) & (tp < n)).all()
        pos = state.pos[k]
        assert len({tuple(a) for a in pos}) == 8 and ((pos >= 0) & (pos < n)).all()
        assert not ({tuple(a) for a in pos} & {tuple(t) for t in tp})  # no agent starts on a target
        assert (state.occupant[k, pos[:, 0] + h, pos[:, 1] + h] == np.arange(8)).all()
        assert (state.occupant[k] >= 0).sum() == 8
        assert (state.belief[k, :, 0] == state.p[k]).all() and (state.belief[k, :, 1] == state.u[k]).all()
        assert state.obs_scale[k, 0] == pytest.approx(1.0 / state.p[k].max())
    assert len(set(state.size.tolist())) > 1  # worlds in one batch draw their own side


def test_targets_avoid_obstacles_and_follow_the_prior():
    rng = np.random.default_rng(2)
    n = 30
    p = np.full((n, n), 1e-6)
    p[5:10, 5:10] = 1.0  # nearly all probability in one block
    p /= p.sum()
    u = np.full((n, n), 1.0 / (n * n))
    u[0, 0] = 1.0  # u peaks far from the block, so 1 - u/max(u) is about 1 inside it
    free = np.ones((n, n), bool)
    free[5:7, 5:10] = False
    tp = place_targets(p, u / u.sum(), free, 10, rng)
    assert free[tp[:, 0], tp[:, 1]].all()
    assert ((tp[:, 0] >= 7) & (tp[:, 0] < 10) & (tp[:, 1] >= 5) & (tp[:, 1] < 10)).all()


def test_uncertainty_rejects_targets():
    """Where u is at its maximum, 1 - u/max(u) = 0: no target may be placed there."""
    rng = np.random.default_rng(3)
    n = 10
    p = np.full((n, n), 1.0 / n**2)
    u = np.zeros((n, n))
    u[:, :5] = 1.0  # left half at max uncertainty
    u[:, 5:] = 0.5
    tp = place_targets(p, u / u.sum(), np.ones((n, n), bool), 20, rng)
    assert (tp[:, 1] >= 5).all()


def test_obstacles_are_blocked_and_free_of_agents_and_targets():
    config = WorldConfig(world_size=(30, 30), n_agents=16)
    state = allocate(config, 2)
    reset_worlds(config, state, np.ones(2, bool), np.random.default_rng(4), Scenario(IidObstacles(0.2)))
    h = state.halo
    for k in range(2):
        inner_blocked = state.blocked[_inner(state, k)]
        assert 0.1 < inner_blocked.mean() < 0.3
        assert (state.p[_inner(state, k)][inner_blocked] == 0).all()  # obstacles hold no information
        assert (state.u[_inner(state, k)][inner_blocked] == 0).all()
        assert state.p[k].sum() == pytest.approx(1.0, rel=1e-5) and state.u[k].sum() == pytest.approx(1.0, rel=1e-5)
        assert not state.blocked[k, state.pos[k, :, 0] + h, state.pos[k, :, 1] + h].any()
        tp = state.target_pos[k, : state.n_targets[k]]
        assert not state.blocked[k, tp[:, 0] + h, tp[:, 1] + h].any()


def test_reset_of_one_world_leaves_the_others_untouched():
    config = WorldConfig(world_size=(20, 30))
    state = allocate(config, 3)
    rng = np.random.default_rng(5)
    reset_worlds(config, state, np.ones(3, bool), rng)
    before = state.copy()
    reset_worlds(config, state, np.array([False, True, False]), rng)
    for name, value in vars(state).items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value[[0, 2]], getattr(before, name)[[0, 2]], err_msg=name)
    assert not np.array_equal(state.p[1], before.p[1])


def test_same_seed_same_world_and_table2_cells_are_expressible():
    # The largest Table 2 cell: n = 160, 32 targets, 64 distributions, up to 256 agents.
    config = WorldConfig(world_size=(160, 160), n_targets=(32, 32), n_distributions=(64, 64), n_agents=256)
    a, b = allocate(config, 1), allocate(config, 1)
    reset_worlds(config, a, np.ones(1, bool), np.random.default_rng(7))
    reset_worlds(config, b, np.ones(1, bool), np.random.default_rng(7))
    for name, value in vars(a).items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value, getattr(b, name), err_msg=name)
    assert a.n_targets[0] == 32 and a.size[0] == 160
