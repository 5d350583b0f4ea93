"""searchrl/reporting/stats.py in process, value by value: efficiency beside the bound, the bounds joined from the
grid's table, Table 3 layouts, the tidy training curves, and the pipe tables every results file is written with.
(The verdicts' boundaries are in test_verdicts.py; the notebooks that call these in test_analysis.py.)"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from searchrl.reporting.stats import (
    beside_paper,
    bootstrap_mean_ci,
    markdown,
    paired_margins,
    summarize,
    table3,
    training_curves,
    with_bounds,
)


def _episodes(found: list[float], bound: list[float] | None, **cell) -> pd.DataFrame:
    cell = {"controller": "x", "model": "b", "n": 40, "N": 4} | cell
    frame = pd.DataFrame({**cell, "map_seed": range(len(found)), "found_fraction": found})
    return frame if bound is None else frame.assign(bound_fraction=bound)


def test_bootstrap_of_one_value_and_of_none():
    assert bootstrap_mean_ci(np.array([0.25])) == (0.25, 0.25, 0.25)
    assert bootstrap_mean_ci([True, False, True, True], n_boot=10)[0] == 0.75  # any numbers, as floats
    with pytest.raises(ValueError, match=r"^bootstrap of an empty sample$"):
        bootstrap_mean_ci(np.array([]))


def test_efficiency_is_the_found_fraction_and_its_ci_over_the_mean_bound():
    """Two maps, repeats averaged first: found 0.25 and 0.75 (mean 0.5), bounds 0.5 and 1.0 (mean 0.75)."""
    episodes = pd.concat([_episodes([0.25, 0.75], [0.5, 1.0]), _episodes([0.25, 0.75], [0.5, 1.0])])
    row = summarize(episodes, n_boot=500).iloc[0]
    assert (row["mean"], row["maps"], row["bound"]) == (0.5, 2, 0.75)
    assert row["efficiency"] == pytest.approx(0.5 / 0.75)
    assert (row["efficiency_low"], row["efficiency_high"]) == pytest.approx((row["low"] / 0.75, row["high"] / 0.75))
    assert list(row.index) == ["controller", "model", "n", "N", "mean", "low", "high", "maps", "bound", "efficiency",
                               "efficiency_low", "efficiency_high"]  # fmt: skip
    assert row["low"] == 0.25 and row["high"] == 0.75  # two maps: the resampled means are 0.25, 0.5 or 0.75


def test_a_cell_without_bounds_has_no_efficiency_and_a_missing_bound_is_nan():
    plain = summarize(_episodes([0.5, 1.0], None), n_boot=100)
    assert list(plain.columns) == ["controller", "model", "n", "N", "mean", "low", "high", "maps"]
    gap = summarize(_episodes([0.5, 1.0], [0.5, np.nan]), n_boot=100).iloc[0]  # one map run before bounds
    assert gap["mean"] == 0.75 and math.isnan(gap["bound"]) and math.isnan(gap["efficiency"])
    nan_found = summarize(_episodes([0.5, np.nan], None), n_boot=100).iloc[0]  # a damaged episode is not skipped
    assert math.isnan(nan_found["mean"])


def test_summary_keeps_cells_and_controllers_apart():
    episodes = pd.concat(
        [
            _episodes([0.0, 1.0], None),
            _episodes([1.0, 1.0], None, N=8),
            _episodes([0.5, 0.5], None, controller="y"),
            _episodes([0.25, 0.25], None, model="c"),
        ]
    )
    rows = summarize(episodes, n_boot=100)
    assert rows[["controller", "model", "N", "mean", "maps"]].values.tolist() == [
        ["x", "b", 4, 0.5, 2], ["x", "b", 8, 1.0, 2], ["x", "c", 4, 0.25, 2], ["y", "b", 4, 0.5, 2]]  # fmt: skip


def test_summary_of_another_metric():
    episodes = _episodes([0.5, 0.5], None).assign(L=[100, 200])
    assert summarize(episodes, metric="L", n_boot=100)["mean"].item() == 150


def test_with_bounds_joins_each_cells_bound_and_divides_by_it():
    summary = pd.DataFrame({"controller": "x", "model": "b", "n": [40, 40, 80], "N": [1, 2, 1],
                            "mean": [0.2, 0.4, 0.3], "low": [0.1, 0.3, 0.2], "high": [0.3, 0.5, 0.4],
                            "bound": [9.0, 9.0, 9.0]})  # a stale bound column is replaced  # fmt: skip
    bounds = pd.DataFrame({"n": [40, 40, 80], "N": [1, 2, 1], "bound": [0.5, 0.8, 0.6], "mc_stderr": [0.01] * 3,
                           "detection_bound": [0.4, 0.5, 0.5], "detection_mc_stderr": [0.02] * 3,
                           "min": [0.0] * 3})  # fmt: skip
    merged = with_bounds(summary, bounds)
    assert merged["bound"].tolist() == [0.5, 0.8, 0.6] and merged["mc_stderr"].tolist() == [0.01] * 3
    assert merged["efficiency"].tolist() == pytest.approx([0.4, 0.5, 0.5])
    assert merged["efficiency_low"].tolist() == pytest.approx([0.2, 0.375, 0.2 / 0.6])
    assert merged["efficiency_high"].tolist() == pytest.approx([0.6, 0.625, 0.4 / 0.6])
    assert merged["detection_bound"].tolist() == [0.4, 0.5, 0.5]
    assert merged["detection_efficiency"].tolist() == pytest.approx([0.5, 0.8, 0.6])
    assert "min" not in merged and len(merged) == 3
    cell_only = with_bounds(summary.iloc[:2], bounds[["n", "N", "bound", "mc_stderr"]])
    assert "detection_bound" not in cell_only and "detection_efficiency" not in cell_only
    missing = with_bounds(summary, bounds.iloc[:2])  # a cell the bounds table lacks: NaN, the row kept
    assert len(missing) == 3 and math.isnan(missing["efficiency"].iloc[2])
    with pytest.raises(pd.errors.MergeError):  # two bounds for one cell cannot be joined
        with_bounds(summary, pd.concat([bounds, bounds.iloc[:1]]))


def test_table3_has_a_row_per_team_and_a_column_per_world():
    summary = pd.DataFrame({"controller": "x", "model": "b", "n": [20, 20, 40], "N": [1, 2, 1],
                            "mean": [0.1, 0.2, 0.3], "low": [0.0, 0.1, 0.2]})  # fmt: skip
    wide = table3(summary)
    assert wide.index.tolist() == [("x", "b", 1), ("x", "b", 2)] and wide.columns.tolist() == [20, 40]
    assert wide.loc[("x", "b", 1), 40] == 0.3 and math.isnan(wide.loc[("x", "b", 2), 40])
    assert table3(summary, "low").loc[("x", "b", 2), 20] == 0.1


def test_beside_paper_matches_models_regardless_of_case():
    ours = pd.DataFrame({"controller": "x", "model": ["b", "diagonal"], "n": 20, "N": 1, "mean": [0.5, 0.6]})
    paper = pd.DataFrame({"model": ["B", "Diagonal", "B"], "n": [20, 20, 40], "N": 1, "found_fraction": [0.4, 0.7, 1]})
    merged = beside_paper(ours, paper)
    assert merged["paper"].tolist() == [0.4, 0.7] and merged["diff"].tolist() == pytest.approx([0.1, -0.1])
    assert merged["model"].tolist() == ["b", "diagonal"] and "key" not in merged


def test_markdown_rounds_numbers_and_shows_nan_as_a_dash():
    frame = pd.DataFrame({"cell": [1, 2], "mean": [0.12345, np.nan], "who": ["x", "y"]}).set_index("cell")
    assert markdown(frame) == "| cell | mean | who |\n|---|---|---|\n| 1 | 0.123 | x |\n| 2 | – | y |\n"
    assert markdown(frame, digits=1).splitlines()[2] == "| 1 | 0.1 | x |"
    wide = pd.DataFrame([[1.0, 2.0]], columns=pd.MultiIndex.from_tuples([("mean", 20), ("mean", 40)]))
    assert markdown(wide).splitlines()[0] == "| index | mean 20 | mean 40 |"


def test_training_curves_are_tidy_per_run_with_the_model_from_its_config(tmp_path):
    for name, model in (("b_run", "b"), ("bare", None)):
        run = tmp_path / name
        run.mkdir()
        log = {"time/total_timesteps": [0, 1000], "team/found_fraction": [0.5, 0.6],
               "val/found_fraction": [0.4, np.nan], "train/value_loss": [1.0, 2.0],
               "rollout/ep_rew_mean": [3.0, 4.0]}  # fmt: skip
        pd.DataFrame(log).to_csv(run / "progress.csv", index=False)
        if model:
            (run / "config.yaml").write_text(f"model:\n  name: {model}\n")
    (tmp_path / "nomodel").mkdir()
    pd.DataFrame({"time/total_timesteps": [5], "val/found_fraction": [0.9]}).to_csv(
        tmp_path / "nomodel" / "progress.csv", index=False
    )
    (tmp_path / "nomodel" / "config.yaml").write_text("seed: 3\n")
    curves = training_curves([tmp_path / "b_run", tmp_path / "bare", str(tmp_path / "nomodel")])
    assert list(curves.columns) == ["step", "metric", "value", "run", "model", "setting", "seed"]
    seeds = curves.drop_duplicates("run").set_index("run")["seed"]
    assert seeds.to_dict() == {"b_run": 0, "bare": 0, "nomodel": 3}  # a run without config.yaml: seed 0
    assert curves.index.tolist() == list(range(len(curves)))  # one plain index over the runs
    b_run = curves[curves.run == "b_run"]
    assert b_run[["step", "metric", "value"]].values.tolist() == [
        [0, "team/found_fraction", 0.5],
        [1000, "team/found_fraction", 0.6],
        [0, "val/found_fraction", 0.4],
    ]
    assert set(b_run.model) == {"b"} and set(curves[curves.run == "bare"].model) == {"unknown"}
    assert curves[curves.run == "nomodel"][["step", "value", "model"]].values.tolist() == [[5, 0.9, "unknown"]]
    with pytest.raises(FileNotFoundError, match=r"^no run directories given$"):
        training_curves([])


def test_the_summary_bootstraps_with_the_draws_asked_for_and_keeps_a_damaged_repeat():
    found = np.random.default_rng(4).random(12)
    for n_boot in (2000, 300):
        row = summarize(_episodes(list(found), None), n_boot=n_boot).iloc[0]
        assert (row["mean"], row["low"], row["high"]) == bootstrap_mean_ci(found, n_boot)
    default = summarize(_episodes(list(found), None)).iloc[0]
    assert (default["low"], default["high"]) == bootstrap_mean_ci(found)[1:]
    torn = pd.concat([_episodes([0.5, 1.0], None), _episodes([np.nan], None)])  # map 0: 0.5 and a NaN repeat
    assert math.isnan(summarize(torn, n_boot=100)["mean"].item())


def test_paired_margins_rows_name_their_cell_and_use_the_draws_asked_for():
    rng = np.random.default_rng(8)
    rows = []
    for n, agents in ((40, 4), (80, 2)):
        for seed in range(25):
            a, b = rng.random(), rng.random()
            cell = {"model": "b", "n": n, "N": agents, "map_seed": seed}
            rows += [{**cell, "controller": "x", "found_fraction": a}, {**cell, "controller": "y", "found_fraction": b}]
    episodes = pd.DataFrame(rows)
    margins = paired_margins(episodes, "x", "y")
    assert list(margins.columns) == ["controller", "baseline", "n", "N", "mine", "base", "diff", "low", "high", "maps",
                                     "verdict"]  # fmt: skip
    assert margins[["controller", "baseline", "n", "N", "maps"]].values.tolist() == [["x", "y", 40, 4, 25],
                                                                                     ["x", "y", 80, 2, 25]]  # fmt: skip
    for row, (_, cell) in zip(margins.itertuples(), episodes.groupby(["n", "N"]), strict=True):
        diff = (cell[cell.controller == "x"].found_fraction.to_numpy() - cell[cell.controller == "y"].found_fraction
                .to_numpy())  # fmt: skip
        assert (row.diff, row.low, row.high) == pytest.approx(bootstrap_mean_ci(diff), rel=1e-12)
        assert (row.low, row.high) != pytest.approx(bootstrap_mean_ci(diff, 2001)[1:], rel=1e-12)
        few = paired_margins(episodes, "x", "y", n_boot=50)
        assert (few.low.iloc[0], few.high.iloc[0]) != (margins.low.iloc[0], margins.high.iloc[0])
    assert paired_margins(episodes, "x", "y", min_maps=26).verdict.tolist() == ["too few maps"] * 2
    for other, message in (("z", "no episodes of controller 'z' to compare"),):
        with pytest.raises(ValueError) as err:
            paired_margins(episodes, "x", other)
        assert str(err.value) == message
    apart = episodes.assign(map_seed=episodes.map_seed + 100 * (episodes.controller == "y"))
    with pytest.raises(ValueError) as err:
        paired_margins(apart, "x", "y")
    assert str(err.value) == "'x' and 'y' share no map: were they evaluated with the same seed and grid?"
    mixed = pd.concat([episodes, episodes.iloc[:1].assign(model="c")])
    with pytest.raises(ValueError) as err:
        paired_margins(mixed, "x", "y")
    assert str(err.value) == "controller 'x' was evaluated with several models ['b', 'c']: pass episodes of one"


def test_the_papers_table_is_read_with_the_grids_column_names(tmp_path):
    from searchrl.reporting.stats import paper_table3

    (tmp_path / "t.csv").write_text("model,world_size,n_agents,found_fraction\nB,20,1,0.5\n")
    assert paper_table3(tmp_path / "t.csv").to_dict("records") == [{"model": "B", "n": 20, "N": 1,
                                                                     "found_fraction": 0.5}]  # fmt: skip


def test_detection_budget_defaults_to_the_cardinal_moves():
    from searchrl.world.bound import detection_budget, detection_per_move
    from searchrl.world.footprint import GAMMA, MOVES

    assert detection_budget(2, 3) == pytest.approx(2 * (GAMMA.sum() + 2 * detection_per_move(GAMMA, MOVES[:5])))
    assert detection_budget(2, 3) < detection_budget(2, 3, n_actions=9)


def test_outputs_keep_every_row_and_a_plain_index():
    ours = pd.DataFrame({"controller": "x", "model": "b", "n": [20, 80], "N": 1, "mean": [0.5, 0.6]})
    paper = pd.DataFrame({"model": ["B", "B"], "n": [20, 20], "N": [1, 2], "found_fraction": [0.4, 0.5]})
    merged = beside_paper(ours, paper)  # a cell the paper lacks keeps its row, with NaN beside it
    assert len(merged) == 2 and merged["paper"].iloc[0] == 0.4 and math.isnan(merged["paper"].iloc[1])
    summary = pd.DataFrame({"controller": "x", "model": "b", "n": [40], "N": [1], "mean": [0.2], "low": [0.1],
                            "high": [0.3]})  # fmt: skip
    bounds = pd.DataFrame({"n": [40], "N": [1], "bound": [0.5], "mc_stderr": [0.01], "detection_bound": [0.4],
                           "detection_mc_stderr": [0.02]})  # fmt: skip
    assert with_bounds(summary, bounds)["detection_mc_stderr"].tolist() == [0.02]


def test_the_aggregates_match_their_definitions_on_known_scores():
    """rliable's statistics (searchrl/reporting/aggregate.py) on scores with known answers."""
    from searchrl.reporting.aggregate import (
        bootstrap,
        common_tasks,
        interquartile_mean,
        iqm,
        performance_profile,
        probability_of_improvement,
    )

    assert interquartile_mean(np.arange(1, 9)) == 4.5  # 3, 4, 5, 6
    assert interquartile_mean(np.array([0.0, 0.0, 1.0, 1.0, 1.0, 9.0, 9.0, 100.0])) == 3.0  # 1, 1, 1, 9
    low = {("paper", 40, 1): np.array([0.1, 0.2, 0.3]), ("paper", 80, 2): np.array([0.2, 0.2, 0.4])}
    high = {task: scores + 0.5 for task, scores in low.items()}
    assert probability_of_improvement(high, low) == 1.0 and probability_of_improvement(low, high) == 0.0
    assert probability_of_improvement(low, low) == 0.5  # every tie counts half
    one = {("paper", 40, 1): np.array([0.1, 0.5]), ("paper", 80, 2): np.array([0.3])}
    assert probability_of_improvement(one, {("paper", 40, 1): np.array([0.3])}) == 0.5  # shared cells only
    assert performance_profile(low, np.array([0.0, 0.15, 0.25, 0.4])).tolist() == [1.0, 5 / 6, 2 / 6, 0.0]
    point, lo, hi = bootstrap(iqm, low, n_boot=300)
    assert lo <= point <= hi and point == iqm(low)
    # the same maps drawn for both controllers: a controller against itself is exactly 0.5 in every draw
    assert bootstrap(probability_of_improvement, low, low, n_boot=50)[1:] == (0.5, 0.5)
    shorter = {("paper", 40, 1): np.array([0.9, 0.8])}
    cut = common_tasks(low, shorter)
    assert list(cut[0]) == [("paper", 40, 1)] and cut[0][("paper", 40, 1)].tolist() == [0.1, 0.2]
    with pytest.raises(ValueError, match="share no cell"):
        common_tasks(low, {("walls", 40, 1): np.array([0.5])})
