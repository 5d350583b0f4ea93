"""The per-map search bound (searchrl/world/bound.py): exact marginals on a tiny map, the same law as the world's
placement, the team's reach, and that a controller's finds stay under it."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from searchrl.world.bound import (
    detection_budget,
    detection_per_move,
    new_cells_per_move,
    placement_weights,
    search_bound,
    target_marginals,
    team_reach,
)
from searchrl.world.footprint import GAMMA, MOVES
from searchrl.world.libm import log  # the C library's log, as target_marginals takes it
from searchrl.world.truth import place_targets

ROOT = Path(__file__).resolve().parents[1]


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


def _detected_mass(paths: np.ndarray, side: int = 128) -> float:
    """Σ_c P_T(c) of agents walking `paths` (N, T, 2) on an open side × side grid: each phase every agent senses
    with Γ around its cell and a target on c stays unfound with probability Π(1 - Γ)."""
    missed = np.ones((side, side))
    for phase in range(paths.shape[1]):
        for row, col in paths[:, phase]:
            missed[row - 2 : row + 3, col - 2 : col + 3] *= 1.0 - GAMMA
    return float((1.0 - missed).sum())


@pytest.mark.parametrize("n_actions", [5, 9])
def test_no_walk_gathers_more_detection_than_the_budget(n_actions):
    """The lemma behind the detection bound, on walks that try hard: straight lines, zigzags, random walks, and
    agents crossing; each phase adds at most D, the first ΣΓ, and one move from a fresh footprint adds exactly D."""
    rng, steps = np.random.default_rng(0), 40
    moves = MOVES[1:n_actions]
    walks = [np.repeat(moves[[i]], steps - 1, axis=0) for i in range(len(moves))]  # straight on
    walks += [moves[np.arange(steps - 1) % 2 + i] for i in range(len(moves) - 1)]  # zigzags
    walks += [moves[rng.integers(len(moves), size=steps - 1)] for _ in range(20)]  # random walks
    for n_agents in (1, 3):
        for _ in range(len(walks)):
            chosen = [walks[i] for i in rng.choice(len(walks), n_agents)]
            starts = rng.integers(60, 68, size=(n_agents, 1, 2))  # 39 moves stay inside
            paths = starts + np.concatenate([np.zeros((n_agents, 1, 2), np.int64), np.cumsum(chosen, axis=1)], 1)
            assert _detected_mass(paths) <= detection_budget(n_agents, steps, n_actions) + 1e-9
    one_move = [_detected_mass(np.array([[[32, 32], [32 + dr, 32 + dc]]])) for dr, dc in MOVES[:n_actions]]
    assert max(one_move) == pytest.approx(detection_budget(1, 2, n_actions))
    assert detection_per_move(moves=MOVES[:n_actions]) == pytest.approx(3.169 if n_actions == 5 else 3.768, abs=1e-3)
    assert detection_budget(8, 256, n_actions) < team_reach(8, 256, n_actions)  # tighter than the cells' count


def test_the_detection_bound_is_the_cell_bound_with_a_fractional_budget():
    p, u, free = _tiny_map(4)
    whole = search_bound(p, u, free, 3, 4, 2000, np.random.default_rng(5), budgets=(4.0,))
    assert whole.detection[0] == pytest.approx(whole.expected)  # same draws, same cells
    part = search_bound(p, u, free, 3, 5, 2000, np.random.default_rng(5), budgets=(4.5, 5.0))
    fewer = search_bound(p, u, free, 3, 4, 2000, np.random.default_rng(5))
    assert fewer.expected < part.detection[0] < part.expected  # half of the fifth cell's mass
    assert part.detection[0] == pytest.approx((fewer.expected + part.expected) / 2)
    assert part.detection[1] == pytest.approx(part.expected)  # each budget on the same draws


def test_the_bound_is_the_mean_count_on_the_top_cells_and_its_stderr_that_mean_s():
    """expected = the mean over draws of the targets on the `reach` cells of largest marginal; stderr = their
    sample standard deviation / √draws (the Monte Carlo error of that mean, not the spread of one draw)."""
    p, u, free = _tiny_map(6)
    bound = search_bound(p, u, free, 3, 4, 1600, np.random.default_rng(9))
    marginals, chosen = target_marginals(placement_weights(p, u, free), 3, 1600, np.random.default_rng(9))
    top = np.argsort(-marginals.ravel(), kind="stable")[:4]
    per_draw = np.isin(chosen, top).sum(axis=1)
    assert (bound.expected, bound.reach, bound.draws) == (pytest.approx(per_draw.mean()), 4, 1600)
    assert bound.stderr == pytest.approx(per_draw.std(ddof=1) / 40.0)
    assert 0 < bound.stderr < 0.05


def test_the_bound_grows_with_reach_and_saturates_at_the_target_count():
    p, u, free = _tiny_map(4)
    bounds = [search_bound(p, u, free, 3, k, 2000, np.random.default_rng(5)).expected for k in range(1, 9)]
    assert all(a <= b for a, b in itertools.pairwise(bounds)) and bounds[-1] == pytest.approx(3)
    assert bounds[2] < 3  # three cells do not hold all three targets every time


@pytest.mark.parametrize("controller", ["surfing", "greedy_target"])
def test_no_controller_finds_more_than_the_bound(controller):
    """On the hardest small cells (one agent, n = 40 and 80) the bound binds least loosely; a controller's mean
    found fraction stays under the mean bound fraction of the same maps."""
    from searchrl.controllers.registry import make_controller
    from searchrl.evaluate.cell_bounds import cell_bounds
    from searchrl.evaluate.grid import Cell, map_seed
    from searchrl.evaluate.runner import cell_config, run_cell
    from searchrl.world.config import WorldConfig

    world = WorldConfig(n_agents=1, explicit_area=5, communication=True)
    for index, cell in enumerate([Cell(40, 1, 8, 16), Cell(80, 1, 16, 32)]):
        episodes = run_cell(lambda config, seed: make_controller(controller, config, seed=seed), world, cell, index,
                            maps=6, repeats=1, seed=10**6, needs_observation=False)  # fmt: skip
        bounds = cell_bounds(world, cell, [map_seed(10**6, index, m) for m in range(6)], draws=400)
        assert (bounds.reach == 13 + 5 * (cell_config(world, cell).max_steps - 1)).all()
        joined = episodes.merge(bounds, on="map_seed")
        assert len(joined) == 6 and joined.found_fraction.mean() <= joined.bound_fraction.mean()


def test_the_cache_gives_the_same_bounds_and_only_for_the_same_map(tmp_path):
    from searchrl.evaluate.cell_bounds import cell_bounds
    from searchrl.evaluate.grid import Cell
    from searchrl.world.config import WorldConfig

    world, cell, seeds = WorldConfig(), Cell(20, 2, 4, 8), [11, 12, 13]
    fresh = cell_bounds(world, cell, seeds, draws=200)
    assert cell_bounds(world, cell, seeds[:2], draws=200, cache=tmp_path).equals(fresh.iloc[:2])
    assert cell_bounds(world, cell, seeds, draws=200, cache=tmp_path).equals(fresh)  # two read, one added
    # on threads, cached and new rows mixed, in the order of the seeds asked for
    assert (
        cell_bounds(world, cell, [*seeds[::-1], 14], 200, tmp_path, workers=3)
        .iloc[:3]
        .equals(fresh.iloc[::-1].reset_index(drop=True))
    )
    assert cell_bounds(world, cell, [14, *seeds], 200, workers=2).equals(cell_bounds(world, cell, [14, *seeds], 200))
    cached = pd.read_parquet(tmp_path / "n20_N2_draws200.parquet")
    assert sorted(cached.map_seed) == [*seeds, 14]
    cached.loc[:, "bound"] = -1.0  # a row is reused only for its own map: another digest is recomputed
    cached.loc[:, "digest"] = "another map"
    cached.to_parquet(tmp_path / "n20_N2_draws200.parquet")
    assert cell_bounds(world, cell, seeds, draws=200, cache=tmp_path).equals(fresh)
    cached = pd.read_parquet(tmp_path / "n20_N2_draws200.parquet")  # the right maps, rows of another reach
    cached.loc[:, "bound"] = -1.0
    cached.loc[:, "team_reach"] += 5
    cached.to_parquet(tmp_path / "n20_N2_draws200.parquet")
    assert cell_bounds(world, cell, seeds, draws=200, cache=tmp_path).equals(fresh)


def test_a_world_reads_the_detection_bound_of_its_own_moves_from_one_cached_row(tmp_path):
    """Cardinal and diagonal detection bounds come from the same draws, stored in one row per map: a diagonal world
    reads its (larger) bound from the rows a cardinal one wrote, and the cell bound is the same for both."""
    from dataclasses import replace

    from searchrl.evaluate.cell_bounds import cell_bounds
    from searchrl.evaluate.grid import Cell
    from searchrl.world.config import WorldConfig

    cardinal, cell, seeds = WorldConfig(), Cell(80, 1, 16, 32), [11, 12]  # unsaturated: one agent, n = 80
    straight = cell_bounds(cardinal, cell, seeds, draws=200, cache=tmp_path, detection=True)
    written = (tmp_path / "n80_N1_draws200.parquet").stat().st_mtime_ns
    diagonal = cell_bounds(replace(cardinal, diagonal=True), cell, seeds, draws=200, cache=tmp_path, detection=True)
    assert (tmp_path / "n80_N1_draws200.parquet").stat().st_mtime_ns == written  # read, not computed again
    assert diagonal["bound"].equals(straight["bound"])
    assert (straight.detection_bound < diagonal.detection_bound).all()
    assert (diagonal.detection_bound <= diagonal.bound).all()


def test_the_maps_and_so_the_bounds_do_not_depend_on_the_model_or_the_sensing():
    """analysis/bounds.py computes one table of bounds for every model and world: that holds while a map is a
    function of the cell and its seed alone."""
    from dataclasses import replace

    from searchrl.evaluate.cell_bounds import map_prior
    from searchrl.evaluate.grid import Cell
    from searchrl.evaluate.runner import cell_config
    from searchrl.world.config import WorldConfig

    base, cell = WorldConfig(), Cell(40, 2, 8, 16)
    variants = [replace(base, explicit_area=11, communication=False), replace(base, diagonal=True),
                replace(base, k=0.0, k_per_n=1.0), replace(base, belief_age=0.9)]  # fmt: skip
    reference = map_prior(cell_config(base, cell), 123)
    for variant in variants:
        assert all(np.array_equal(a, b) for a, b in zip(reference, map_prior(cell_config(variant, cell), 123),
                                                        strict=True))  # fmt: skip


TABLES = [ROOT / "analysis" / "out" / "bounds" / "efficiency.csv"]


def test_no_controller_of_the_shipped_tables_exceeds_the_bound_on_any_cell():
    """The full-grid check: every controller with results in docs (analysis/out/bounds/efficiency.csv, made by
    analysis/bounds.py from the Table 3 and calibration tables) stays under the per-cell bound on all 30 cells,
    allowing 3 Monte Carlo standard errors of the bound's mean."""
    joined = pd.read_csv(TABLES[0])
    assert set(joined.groupby(["table", "world", "controller", "model"]).size()) == {30}  # every cell of the grid
    assert (joined["mean"] <= joined["bound"] + 3 * joined["mc_stderr"]).all()
    assert joined.detection_bound.notna().all()  # each model's against the detection bound of its own moves
    assert (joined["mean"] <= joined["detection_bound"] + 3 * joined["detection_mc_stderr"]).all()
    assert (joined["detection_bound"] <= joined["bound"] + 1e-9).all()
    diagonal, cardinal = joined[joined.model == "diagonal"], joined[joined.model != "diagonal"]
    assert diagonal.detection_bound.mean() > cardinal.detection_bound.mean()  # more detection per diagonal move


def test_the_grids_table_summarises_each_cells_maps(tmp_path, capsys):
    """grid_bounds (analysis/bounds.py's table): per cell the mean, extremes and Monte Carlo error of its maps'
    bound fractions, the detection budget and the mean detection bound, from the same rows cell_bounds gives."""
    from dataclasses import replace

    from searchrl.evaluate.cell_bounds import cell_bounds, grid_bounds
    from searchrl.evaluate.grid import Cell, map_seed
    from searchrl.world.config import WorldConfig

    world, cells = WorldConfig(), [Cell(80, 1, 16, 32), Cell(80, 2, 16, 32)]  # unsaturated: the bound binds
    table = grid_bounds(world, cells, maps=3, seed=50, draws=150, cache=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["n80_N1_draws150.parquet", "n80_N2_draws150.parquet"]
    assert list(table.columns) == ["n", "N", "targets", "maps", "reach", "bound", "mc_stderr", "min", "max", "budget",
                                   "detection_bound", "detection_mc_stderr"]  # fmt: skip
    for index, (cell, row) in enumerate(zip(cells, table.itertuples(), strict=True)):
        maps = cell_bounds(world, cell, [map_seed(50, index, m) for m in range(3)], 150, tmp_path, detection=True)
        assert (row.n, row.N, row.targets, row.maps, row.reach) == (80, cell.n_agents, 16, 3, maps.reach.iloc[0])
        assert (row.bound, row.min, row.max) == pytest.approx(
            (maps.bound_fraction.mean(), maps.bound_fraction.min(), maps.bound_fraction.max()))  # fmt: skip
        assert row.mc_stderr == pytest.approx(np.sqrt((maps.bound_stderr**2).sum()) / 3 / 16)
        assert row.budget == pytest.approx(detection_budget(cell.n_agents, 256, 5))
        assert row.detection_bound == pytest.approx(maps.detection_fraction.mean())
        assert row.detection_mc_stderr == pytest.approx(np.sqrt((maps.detection_stderr**2).sum()) / 3 / 16)
        assert 0 <= row.mc_stderr < row.bound <= 1 and 0 < row.detection_mc_stderr < row.detection_bound < 1
    assert capsys.readouterr().out.splitlines()[0].startswith("n80_N1: bound fraction 0.")
    diagonal = grid_bounds(replace(world, diagonal=True), cells[:1], maps=1, seed=50, draws=150, cache=None)
    assert diagonal.budget.item() == pytest.approx(detection_budget(1, 256, 9)) and diagonal.maps.item() == 1


def test_a_maps_digest_names_its_prior_obstacles_and_count_in_16_hex_digits():
    """Cached rows are reused by map seed and digest: the digest must change with anything the bound reads, and keep
    its length, or the rows cached so far would never match again."""
    from searchrl.evaluate.cell_bounds import map_digest

    p, u, free = _tiny_map(1)
    digest = map_digest(p, u, free, 3)
    assert len(digest) == 16 and int(digest, 16) >= 0 and digest == map_digest(p.copy(), u, free, 3)
    blocked = free.copy()
    blocked[0, 0] = False
    others = [map_digest(p[::-1].copy(), u, free, 3), map_digest(p, u[::-1].copy(), free, 3),
              map_digest(p, u, blocked, 3), map_digest(p, u, free, 4)]  # fmt: skip
    assert len({digest, *others}) == 5


def test_cell_bounds_gives_the_detection_bound_only_when_asked(tmp_path):
    from searchrl.evaluate.cell_bounds import BOUND_COLUMNS, cell_bounds
    from searchrl.evaluate.grid import Cell
    from searchrl.world.config import WorldConfig

    plain = cell_bounds(WorldConfig(), Cell(20, 1, 4, 8), [5], draws=100)
    assert list(plain.columns) == ["map_seed", *BOUND_COLUMNS, "reach"]
    assert plain.reach.tolist() == [min(team_reach(1, 256, 5), 20 * 20)]  # at most the world's cells


def test_the_detection_bound_of_a_cell_is_its_budgets_share_of_the_same_draws():
    from searchrl.evaluate.cell_bounds import cell_bounds, map_prior
    from searchrl.evaluate.grid import Cell
    from searchrl.evaluate.runner import cell_config
    from searchrl.world.config import WorldConfig

    world, cell = WorldConfig(), Cell(80, 2, 16, 32)
    row = cell_bounds(world, cell, [7], draws=120, detection=True).iloc[0]
    p, u, free = map_prior(cell_config(world, cell), 7)
    direct = search_bound(p, u, free, 16, team_reach(2, 256, 5), 120, np.random.default_rng([7, 29]),
                          budgets=(detection_budget(2, 256, 5),))  # fmt: skip
    assert (row.bound, row.detection_bound) == pytest.approx((direct.expected, direct.detection[0]))
    assert row.detection_fraction == pytest.approx(direct.detection[0] / 16)


def test_a_cache_file_of_another_layout_is_computed_afresh_and_replaced(tmp_path):
    from searchrl.evaluate.cell_bounds import cell_bounds
    from searchrl.evaluate.grid import Cell
    from searchrl.world.config import WorldConfig

    world, cell = WorldConfig(), Cell(20, 2, 4, 8)
    fresh = cell_bounds(world, cell, [11, 12], draws=100)
    pd.DataFrame({"map_seed": [11, 12], "bound": [-1.0, -1.0]}).to_parquet(tmp_path / "n20_N2_draws100.parquet")
    assert cell_bounds(world, cell, [11, 12], draws=100, cache=tmp_path).equals(fresh)
    assert {"digest", "team_reach"} <= set(pd.read_parquet(tmp_path / "n20_N2_draws100.parquet").columns)


@pytest.mark.parametrize("setting", ["prob_variance_scale", "unc_variance_scale"])
def test_a_cached_row_is_not_reused_for_another_prior_of_the_same_seed(tmp_path, setting):
    """Another world setting draws another p (or u) from the same map seed: the cache must compute that map's bound,
    not reuse the row of the map it holds for the seed."""
    from dataclasses import replace

    from searchrl.evaluate.cell_bounds import cell_bounds, map_prior
    from searchrl.evaluate.grid import Cell
    from searchrl.evaluate.runner import cell_config
    from searchrl.world.config import WorldConfig

    world, cell = WorldConfig(), Cell(80, 1, 16, 32)
    other = replace(world, **{setting: getattr(world, setting) / 4})
    first, second = (map_prior(cell_config(w, cell), 5) for w in (world, other))
    changed = [not np.array_equal(a, b) for a, b in zip(first, second, strict=True)]
    assert changed == ([True, False, False] if setting == "prob_variance_scale" else [False, True, False])
    cell_bounds(world, cell, [5], draws=100, cache=tmp_path)
    assert cell_bounds(other, cell, [5], draws=100, cache=tmp_path).equals(cell_bounds(other, cell, [5], draws=100))


def test_rows_cached_without_the_detection_bound_are_computed_again_when_it_is_asked(tmp_path):
    from searchrl.evaluate.cell_bounds import cell_bounds
    from searchrl.evaluate.grid import Cell
    from searchrl.world.config import WorldConfig

    world, cell, seeds = WorldConfig(), Cell(80, 1, 16, 32), [3, 4]
    cell_bounds(world, cell, seeds[:1], draws=100, cache=tmp_path)  # seed 3 cached without the detection bound
    both = cell_bounds(world, cell, seeds, draws=100, cache=tmp_path, detection=True)
    assert both.equals(cell_bounds(world, cell, seeds, draws=100, detection=True))
    cached = pd.read_parquet(tmp_path / "n80_N1_draws100.parquet")
    assert sorted(cached.map_seed) == seeds and cached.detection_bound_cardinal.notna().all()  # one row per map


def test_a_cache_without_a_cells_file_starts_from_the_shipped_rows(tmp_path, monkeypatch):
    """A first evaluation reads the shipped bounds of its maps and writes them, with those it computes beside them,
    to its own cache; the shipped file is only read."""
    from searchrl.evaluate import cell_bounds as bound_module
    from searchrl.evaluate.grid import Cell
    from searchrl.world.config import WorldConfig

    world, cell, shipped, cache = WorldConfig(), Cell(20, 1, 4, 8), tmp_path / "shipped", tmp_path / "cache"
    bound_module.cell_bounds(world, cell, [3, 4], draws=100, cache=shipped)
    rows = pd.read_parquet(shipped / "n20_N1_draws100.parquet")
    rows.loc[rows.map_seed == 3, "bound"] = 0.5  # a value no computation gives: read, not recomputed
    rows.to_parquet(shipped / "n20_N1_draws100.parquet")
    monkeypatch.setattr(bound_module, "REFERENCE_BOUNDS", shipped)
    got = bound_module.cell_bounds(world, cell, [3, 4, 5], draws=100, cache=cache)
    fresh = bound_module.cell_bounds(world, cell, [4, 5], draws=100)
    assert got.bound.tolist()[0] == 0.5 and got.iloc[1:].reset_index(drop=True).equals(fresh)
    assert sorted(pd.read_parquet(cache / "n20_N1_draws100.parquet").map_seed) == [3, 4, 5]
    assert sorted(pd.read_parquet(shipped / "n20_N1_draws100.parquet").map_seed) == [3, 4]


def test_map_prior_is_the_worlds_n_by_n_maps_without_the_halo(tmp_path):
    from searchrl.evaluate.cell_bounds import cell_bounds, map_prior
    from searchrl.evaluate.grid import Cell
    from searchrl.evaluate.runner import cell_config
    from searchrl.world.config import WorldConfig

    p, u, free = map_prior(cell_config(WorldConfig(), Cell(20, 2, 4, 8)), 9)
    assert p.shape == u.shape == free.shape == (20, 20) and p.dtype == u.dtype == np.float64
    assert free.all() and p.sum() == pytest.approx(1.0) and (p > 0).all()  # no obstacles: every cell is inside
    nested = tmp_path / "a" / "b"  # a cache folder is made with its parents
    cell_bounds(WorldConfig(), Cell(20, 2, 4, 8), [9], draws=100, cache=nested)
    assert (nested / "n20_N2_draws100.parquet").exists()


@pytest.mark.parametrize("obstacles", [None, "rooms", "primal"])
def test_map_prior_is_what_a_world_reset_from_the_seed_holds(obstacles):
    """Drawn alone, the map is the one a world's reset writes: p and u as its float32 arrays, free its free cells."""
    from searchrl.evaluate.cell_bounds import map_prior
    from searchrl.evaluate.grid import Cell
    from searchrl.evaluate.runner import cell_config
    from searchrl.world.config import WorldConfig
    from searchrl.world.reset import reset_world
    from searchrl.world.scenario import PAPER, Scenario
    from searchrl.world.state import allocate

    scenario = PAPER if obstacles is None else Scenario.from_dict({"obstacles": {"kind": obstacles}})
    config = cell_config(WorldConfig(), Cell(40, 4, 8, 16))
    for seed in range(4):
        state = allocate(config, 1)
        reset_world(config, state, 0, np.random.default_rng(seed), scenario)
        inner = (0, slice(state.halo, state.halo + 40), slice(state.halo, state.halo + 40))
        p, u, free = map_prior(config, seed, scenario)
        np.testing.assert_array_equal(p, state.p[inner].astype(np.float64))
        np.testing.assert_array_equal(u, state.u[inner].astype(np.float64))
        np.testing.assert_array_equal(free, ~state.blocked[inner])
        assert p.dtype == np.float64 and free.dtype == bool and (scenario is PAPER) == bool(free.all())


def test_a_reach_beyond_every_cell_bounds_all_the_targets():
    p, u, _ = _tiny_map(2)
    every = np.ones((3, 3), bool)  # no obstacle: all 9 cells hold targets with positive probability
    bound = search_bound(p, u, every, 3, 50, 200, np.random.default_rng(1), budgets=(9.0, 40.0))
    assert (bound.expected, bound.reach, bound.detection) == (pytest.approx(3.0), 9, pytest.approx((3.0, 3.0)))
    assert bound.stderr == 0.0


def test_exactly_as_many_cells_of_positive_weight_as_targets_place_them_all_there():
    weights = np.zeros((2, 2))
    weights[0, 0], weights[1, 1] = 0.2, 0.8
    marginals, chosen = target_marginals(weights, 2, 10, np.random.default_rng(0))
    assert marginals.tolist() == [[1.0, 0.0], [0.0, 1.0]] and (np.sort(chosen, axis=1) == [0, 3]).all()
    with pytest.raises(ValueError) as err:
        target_marginals(weights, 3, 10, np.random.default_rng(0))
    assert str(err.value) == "count=3 targets need as many cells of positive weight (2)"


def test_each_draw_places_its_targets_on_the_cells_of_largest_key():
    """Successive sampling as Gumbel top-k: a draw's targets are exactly the `count` cells of largest log w + Gumbel
    noise (one chunk of draws here, so the noise can be drawn again in the same order)."""
    weights = np.random.default_rng(3).random((40, 40))
    _, chosen = target_marginals(weights, 16, 40, np.random.default_rng(8))
    keys = log(weights.ravel()) + np.random.default_rng(8).gumbel(size=(40, 1600))
    top = np.argsort(-keys, axis=1)[:, :16]
    assert all(set(a) == set(b) for a, b in zip(chosen.tolist(), top.tolist(), strict=True))
