"""Analysis notebooks run as scripts on a tiny fixture; statistics helpers; the episode renderer."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import jupytext
import numpy as np
import pandas as pd
import pytest
from PIL import Image

from searchrl.evaluate.results import load
from searchrl.render import main as render_main
from searchrl.reporting.stats import (
    beside_paper,
    bootstrap_mean_ci,
    markdown,
    paired_margins,
    paper_table3,
    summarize,
    table3,
    training_curves,
)
from tests.scripts import run_script as _script

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "analysis").glob("*.py"))
# Scripts that train or evaluate a policy of their own: context_probe.py is run by tests/test_context.py on one,
# guided_b.py (an extension module: parts, networks, teachers) by tests/test_guided.py; compile_time.py,
# label_speed.py, module_trace.py, one_world.py and world_profile.py are benchmarks and traces, run by hand like
# `python -m searchrl.bench` (their kernels' results are the golden slice's and tests/test_threads.py's;
# compile_time.py's one signature a function is tests/test_structure.py's; int8_probe.py times inference paths);
# carry_runs.py and team_reward.py (the lab's long trainings: a carry and a reward), lookahead.py and rollout_own.py
# (extension modules: planners) by tests/test_lab_parts.py
EXPERIMENTS = ("carry_runs.py", "compile_time.py", "context_probe.py", "exit_labels.py", "exit_train.py",
               "guided_b.py", "int8_probe.py", "label_speed.py", "lookahead.py", "module_trace.py", "one_world.py",
               "rollout_own.py", "team_reward.py", "world_profile.py")  # fmt: skip


@pytest.fixture(scope="module")
def fixture_dirs(tmp_path_factory):
    """Three tiny evaluations (surfing, coverage, a tiny model B policy) and that tiny training run."""
    from tests.test_evaluate import _evaluate
    from tests.test_sweep import make_fixture_sweep
    from tests.test_train import TINY, _run

    base = tmp_path_factory.mktemp("analysis")
    for controller in ("surfing", "coverage"):
        _evaluate(base / "eval" / controller, f"controller={controller}", "grid.world_sizes=[20,160]",
                  "grid.max_agents=[2,2]", "grid.n_targets=[4,32]", "grid.n_distributions=[8,64]")  # fmt: skip
    model = _run(base / "run", ["+model=b", *TINY, "total_timesteps=768", "validation.every=256"])
    _evaluate(base / "eval" / "policy", f"checkpoint={model}", "grid.world_sizes=[20,160]", "grid.max_agents=[2,2]",
              "grid.n_targets=[4,32]", "grid.n_distributions=[8,64]")  # fmt: skip
    make_fixture_sweep(base / "sweep")
    return base


def _run_notebook(notebook: str, eval_dirs: list[Path], run_dir: Path, out_dir: Path) -> None:
    args = []
    if notebook == "missed_targets.py":  # it runs a controller itself: a small greedy on two small cells
        args = ["controller=greedy", "controller.reach=2", "controller.seen=true", "grid.maps_per_cell=3",
                "grid.repeats=2"]  # fmt: skip
    if notebook == "bounds.py":  # the whole grid with one map per cell, joined with the shipped Table 3
        args = ["--maps", "1", "--draws", "100", "--cache", str(out_dir / "cache"), "analysis/out/table3.csv"]
    if notebook == "prior_quality.py":  # worlds only, two maps per world size
        args = ["--maps", "2"]
    if notebook == "hedging.py":  # two rules and a policy under the switch on one cell, two maps: small
        args = ["--maps", "2", "--cells", "n40_N1", "--rules", "greedy,coverage",
                "--switch-policy", "term_b_switch=runs/reference/term/b/model.zip@0.5"]  # fmt: skip
    if notebook == "suite.py":  # a small suite run as the shipped ones are, for two rules
        from tests.test_suite import _run

        for controller in ("coverage", "surfing"):
            _run(out_dir / "suite" / controller, f"controller={controller}")
        args = [str(out_dir / "suite"), "--focus", "coverage"]
    if notebook == "oracle_teacher.py":  # the training app with the privileged teacher, a few rollouts
        from tests.test_train import TINY

        args = ["+model=b", *TINY, "total_timesteps=768", "imitation.teacher=oracle_switch", "imitation.epochs=0",
                "imitation.rl_weight=0.5", f"hydra.run.dir={out_dir / 'run'}"]  # fmt: skip
    if notebook == "guided_summary.py":  # a probe as analysis/guided_probe.sh lays it out: two scenarios, then whole
        surfing, coverage, policy = eval_dirs
        for scenario, folders in (("paper", {"path_greedy": surfing, "coverage": coverage, "mine": policy}),
                                  ("sharp", {"coverage": coverage, "mine": surfing})):  # fmt: skip
            (out_dir / "probe" / scenario).mkdir(parents=True)
            for name, source in folders.items():
                (out_dir / "probe" / scenario / name).symlink_to(source)
        args = ["mine", "--probe", str(out_dir / "probe"), "--out", str(out_dir)]
    if notebook == "lookahead_probe.py":  # worlds only: two samples of the smallest cell, two continuations per move
        args = ["--cells", "20x1", "--samples", "2", "--continuations", "2"]
    if notebook == "rollout_table.py":  # a "planner" folder, then the rule folders, the teacher first
        args = [str(eval_dirs[0]), "--rules", str(eval_dirs[1]), str(eval_dirs[2]), "--out", str(out_dir)]
    if notebook == "rollout_probe.py":  # worlds only: two maps of the smallest team cell, one short budget
        args = ["--cells", "20x2", "--maps", "2", "--budgets", "1:3"]
    if notebook == "beyond.py":  # the teacher's folder first, then the policies'
        args = [str(eval_dirs[0]), str(eval_dirs[2]), str(eval_dirs[1]), "--out", str(out_dir)]
    if notebook == "calibration.py":  # folders <root>/<world>/<controller>: here <base>/eval/<controller>
        args = [str(eval_dirs[0].parent.parent), str(out_dir)]
    env = {
        "SEARCHRL_CELLS": os.environ.get("SEARCHRL_CELLS", "n20_N1,n20_N2"),
        "SEARCHRL_LABEL": os.environ.get("SEARCHRL_LABEL", "small"),
        "SEARCHRL_EVAL_DIRS": ",".join(map(str, eval_dirs)),
        "SEARCHRL_RUN_DIRS": str(run_dir),
        "SEARCHRL_SWEEP_DIR": str(eval_dirs[0].parent.parent / "sweep"),
        "SEARCHRL_ANALYSIS_OUT": str(out_dir),
    }
    out = _script(notebook, *args, env=env)
    assert out.returncode == 0, out.stderr[-3000:]


@pytest.mark.slow  # beyond.py three times (about 10 s each)
def test_beyond_fits_the_budget_curve_and_refuses_folders_that_did_not_play_the_teacher_s_maps(fixture_dirs, tmp_path):
    """Three checkpoints of a policy 0.01 better per million agent-steps than the one before (each map's found
    fraction scaled by 0.9, to stay in [0, 1], and raised by that much; its targets counted in thousandths, so each
    is still a whole number of them): the line's slope is 0.01 per million, with no error; a policy folder that lost
    a map is refused in one line; two folders of one name are refused."""
    from omegaconf import OmegaConf

    from searchrl.evaluate.results import cell_files

    teacher = fixture_dirs / "eval" / "surfing"
    folders, runs = [], []
    for million in (1, 2, 4):
        folder = shutil.copytree(fixture_dirs / "eval" / "policy", tmp_path / "eval" / f"at_{million}m")
        record = OmegaConf.load(folder / "evaluation.yaml")
        runs.append(record.controller)
        record.controller = f"{record.controller}@step_{million}000000"
        OmegaConf.save(record, folder / "evaluation.yaml")
        for cell in cell_files(folder):
            frame = pd.read_parquet(cell)
            frame["found_fraction"] = 0.9 * frame["found_fraction"] + 0.01 * million
            frame["targets"] *= 1000
            frame.to_parquet(cell)
        folders.append(str(folder))
    out = _script("beyond.py", str(teacher), *folders, "--out", str(tmp_path / "out"))
    assert out.returncode == 0, out.stderr[-3000:]
    table = pd.read_csv(tmp_path / "out" / "beyond.csv")
    assert np.diff(table.minus_teacher) == pytest.approx([0.01, 0.02])
    last = (tmp_path / "out" / "beyond.md").read_text().splitlines()[-1]
    zero = 1 - table.minus_teacher[0] / 0.01  # the line through (1M, first difference) with slope 0.01 per million
    assert last == (f"The budget curve of {runs[0]} (3 checkpoints), least squares: +0.01000 per million agent-steps "
                    "(standard error 0.00000, 95 % CI [+0.01000, +0.01000], t with 1 degrees of freedom); the line "
                    f"crosses 0 at {zero:.1f}M and +0.02 at {zero + 2:.1f}M.")  # fmt: skip
    cell = cell_files(folders[0])[0]
    frame = pd.read_parquet(cell)
    frame[frame.map_seed != frame.map_seed.iloc[0]].to_parquet(cell)  # a map lost
    out = _script("beyond.py", str(teacher), *folders, "--out", str(tmp_path / "refused"))
    refusal = out.stderr.strip().splitlines()[-1]
    assert out.returncode == 1 and refusal.startswith(f"error: {folders[0]} and {teacher} did not play the same maps")
    twin = shutil.copytree(folders[1], tmp_path / "other" / "at_2m")
    out = _script("beyond.py", str(teacher), folders[1], str(twin), "--out", str(tmp_path / "refused"))
    assert out.returncode == 1 and "two evaluation folders are named 'at_2m'" in out.stderr
    assert not (tmp_path / "refused").exists()  # refused before anything was written


def test_suite_tables_part_of_a_suite_without_its_prior_right_scenario(tmp_path):
    """A part of a suite (`suite_scenarios=`) that holds one severity and not the prior right: the tables say which
    severities they average and show the prior right's column as missing, and a pipe table's separator has as many
    columns as its header."""
    from tests.test_suite import _run

    for controller in ("coverage", "surfing"):
        _run(tmp_path / "suite" / controller, f"controller={controller}", "suite_scenarios=[*+*1]")
    out = _script("suite.py", str(tmp_path / "suite"), "--out", str(tmp_path / "out"))
    assert out.returncode == 0, out.stderr[-3000:]
    family = (tmp_path / "out" / "family.md").read_text().splitlines()[0]
    assert "no results for 1 of the suite's 3 scenarios (var1)" in family, family
    assert family.endswith("a family's column averages its severities 1"), family
    header, separator, *rows = (tmp_path / "out" / "severity.md").read_text().splitlines()
    assert header == "| controller | family | 0 | 1 |" and separator == "|---|---|---|---|"
    assert len(rows) == 4 and all(row.split(" | ")[2] == "–" for row in rows)


# context_probe.py needs a policy trained with the context: tests/test_context.py runs it on one
# hedging.py runs rules and a shipped policy itself (about 50 s): in the slow run
# beyond.py tabulates research folders (about 30 s): in the slow run
SLOW_NOTEBOOKS = ("hedging.py", "beyond.py")


@pytest.mark.parametrize("notebook", [pytest.param(p.name, marks=pytest.mark.slow) if p.name in SLOW_NOTEBOOKS
                                      else p.name for p in NOTEBOOKS if p.name not in EXPERIMENTS])  # fmt: skip
def test_notebook_runs_on_the_fixture(fixture_dirs, notebook, tmp_path):
    eval_dirs = [fixture_dirs / "eval" / c for c in ("surfing", "coverage", "policy")]
    _run_notebook(notebook, eval_dirs, fixture_dirs / "run", tmp_path)
    # Every output file, exactly: a CSV's (rows, columns), a PNG's pixel size (figsize x dpi), a Markdown file's
    # first line and its number of table lines. efficiency.csv has a row per row of the shipped analysis/out/table3.csv.
    shipped = len(pd.read_csv(ROOT / "analysis" / "out" / "table3.csv"))
    expected = {
        "table3.py": {"table3.csv": (12, 15), "table3.md": ("Covers:", 8), "table3_vs_paper.md": ("Covers:", 4),
                      "table3_efficiency.md": ("Covers:", 13)},
        "bounds.py": {"bounds.csv": (30, 15), "bounds.md": ("Mean bound fraction per cell (1 maps, 100 placements per "
                                                            "map; the largest Monte Carlo standard error", 33),
                      "efficiency.csv": (shipped, 17), "efficiency.md": (f"Upper-bound check: 0 of {shipped} cells "
                                                                         "have a mean above the bound", None)},
        "figures.py": {"fig7_n160.png": (720, 480), "fig8_all_sizes.png": (768, 768)},
        "training_curves.py": {"training_curves.png": (1980, 360), "training_curves.csv": (46, 7),
                               "training_convergence.md": ("Validation found fraction:", 6),
                               "validation.md": ("| step | run |", 5)},
        "claims.py": {"margins.csv": (8, 11), "margins.md": ("### policy:run − surfing", 8),
                      "claims.md": ("# Claims", 9)},
        "compare.py": {"compare.csv": (8, 11), "compare.md": ("# surfing against coverage, policy", 8)},
        "missed_targets.py": {"small.csv": (2, 11),
                              "missed_targets.md": ("# Missed targets by distance to the edge", 4)},
        "calibration.py": {"calibration.csv": (12, 16), "calibration.png": (880, 396),
                           "calibration.md": ("# Which k: heuristics in four worlds beside the paper", 11)},
        "prior_quality.py": {"prior_quality.csv": (2 * 4 * 5 * 3, 9),
                             "prior_quality.md": ("Mean prior quality over 2 maps per n", 10)},
        "hedging.py": {"hedging.csv": (3 * (1 + 7 * 2), 7),
                       "hedging.md": ("Mean found fraction on tuning seeds (2 maps per cell; cells n40_N1", 5)},
        "suite.py": {"family.md": ("Mean found fraction, 95 % CI over maps (8 maps", 4),
                     "severity.md": ("| controller | family | 0 | 1 |", 6), "tail.md": ("Worst-10 % tail", 4),
                     "compare.md": ("coverage minus each controller", None), "suite.png": (440, 770),
                     "moves.md": ("Blocked / stale: per family, the mean share of a team's moves a wall or agent", 4),
                     "quality.md": ("Mean found fraction per bin of prior quality (the same episodes for every", None)},
        "oracle_teacher.py": {},
        "lookahead_probe.py": {"samples.csv": (2, 12), "probe.md": ("| n | N | samples | found_by_teacher |", 3)},
        "rollout_table.py": {"rollout.csv": (4, 22),
                             "rollout.md": ("# The rollout planner against coverage and the best of coverage", 6),
                             "budgets.md": ("# Each planner minus coverage (95 % CI over maps)", 6)},
        "rollout_probe.py": {"episodes.csv": (4, 8), "probe.csv": (1, 14),
                             "probe.md": ("| n | N | budget | maps | teacher_found |", 3)},
        "guided_summary.py": {"summary.md": ("Mean found fraction per scenario; beside each baseline: mine", 5),
                              "best_rule.md": ("mine against the best rule of each scenario", 5),
                              "tail.md": ("Worst-10 % tail: per scenario and cell", 5)},
        "beyond.py": {"beyond.csv": (2, 10), "beyond.png": (600, 384),
                      "beyond.md": ("Each policy minus surfing over surfing: scenario paper", 4)},
        "report.py": {"report.csv": (3, 6), "improvement.csv": (2, 5), "report.png": (1200, 432),
                      "report.md": ("Over 4 cells and ", 9)},
        "shipped.py": {"shipped.md": ("| policy | RL agent-steps | RL hours (1 core) | policy found | paper |", 6)},
        "sweep.py": {"sweep.csv": (2, 5), "sweep.md": ("| algo.learning_rate | seeds | score | low | high |", 4),
                     "sweep_curves.png": (780, 480)},
    }[notebook]  # fmt: skip
    assert sorted(p.name for p in tmp_path.glob("*.*")) == sorted(expected)
    for name, want in expected.items():
        path = tmp_path / name
        if path.suffix == ".csv":
            assert pd.read_csv(path).shape == want, name
        elif path.suffix == ".png":
            with Image.open(path) as image:
                assert (image.format, image.size) == ("PNG", want), name
        else:
            lines = path.read_text().splitlines()
            assert lines[0].startswith(want[0]), (name, lines[0])
            assert want[1] is None or sum(line.startswith("|") for line in lines) == want[1], name
    if notebook == "guided_summary.py":  # whole: each map's mean over both scenarios, for the controllers of both
        lines = (tmp_path / "summary.md").read_text().splitlines()
        cells = [[c.strip() for c in line.strip("|").split("|")] for line in lines if line.startswith(("| s", "| w"))]
        row = dict(zip(cells[0], cells[-1], strict=True))
        assert cells[-1][0] == "whole", cells
        assert row["path_greedy"] == "" and row["coverage"].endswith(", 24 maps)")  # not run under sharp
        assert row["best rule"].startswith("coverage")
    if notebook == "missed_targets.py":  # every unfound target is counted once, in one distance bin
        rows = pd.read_csv(tmp_path / "small.csv")
        assert list(rows.cell) == ["n20_N1", "n20_N2"] and (rows.episodes == 6).all()
        bins = rows[["missed_on_edge", "missed_1_in", "missed_2_in", "missed_3+_in"]].sum(axis=1)
        assert (bins == rows.missed).all()
        assert ((1 - rows.found) * rows.episodes * 4).round().astype(int).tolist() == rows.missed.tolist()
    if notebook == "table3.py":
        table = pd.read_csv(tmp_path / "table3.csv")
        assert set(table.controller) == {"surfing", "coverage", "policy:run"} and table["paper"].notna().all()
        assert (table["low"] <= table["mean"]).all() and (table["mean"] <= table["high"]).all()
        assert (table["mean"] <= table["bound"]).all()  # the fixture's episodes carry their maps' bounds
        assert (table["efficiency"] == table["mean"] / table["bound"]).all()
        policy = table[table.controller == "policy:run"].iloc[0]
        assert f"{policy['mean']:.3f} ({policy['paper']:.2f})" in (tmp_path / "table3_vs_paper.md").read_text()
        covers = (tmp_path / "table3.md").read_text().split("\n\n")[0].splitlines()  # each folder: what it holds
        assert len(covers) == 4 and all("scenario paper, seed" in line and " cells" in line for line in covers[1:])
    if notebook == "compare.py":  # the first directory against each other one, labelled by folder name
        compared = pd.read_csv(tmp_path / "compare.csv")
        assert set(zip(compared.controller, compared.baseline, strict=True)) == {("surfing", "coverage"),
                                                                               ("surfing", "policy")}  # fmt: skip
        assert len(compared) == 2 * 4 and "## surfing − policy" in (tmp_path / "compare.md").read_text()
    if notebook == "claims.py":
        margins = pd.read_csv(tmp_path / "margins.csv")
        pairs = set(zip(margins.controller, margins.baseline, strict=True))
        assert pairs == {("policy:run", "surfing"), ("policy:run", "coverage")}
        assert len(margins) == 2 * 4 and (margins.maps == 3).all()  # 4 cells, 3 maps each
        claims = (tmp_path / "claims.md").read_text()  # the fixture has no cell with n >= 40 and N >= 4
        assert ("## 1. DRL beats information surfing (cells with n ≥ 40 and N ≥ 4)\n\n- b: no evaluated cell in this "
                "region\n\nCells of that region where a policy does not find more than surfing (tie, saturated or "
                "worse):\n\n(none)\n\nAll cells:\n\n- b: better on 0 of 4 cells, tie 0, saturated 0, worse 0, too few "
                "maps 4; smallest margin ") in claims  # fmt: skip
        assert "## Efficiency against the search bound" in claims
    if notebook == "shipped.py":  # made from shipped files only: the README's table is what it writes
        assert (tmp_path / "shipped.md").read_text() == (ROOT / "analysis" / "out" / "shipped.md").read_text()
    if notebook == "bounds.py":
        bounds = pd.read_csv(tmp_path / "bounds.csv")
        assert len(bounds) == 30 and (bounds.maps == 1).all() and bounds.bound.between(0, 1).all()
        assert len(list((tmp_path / "cache").glob("*.parquet"))) == 30  # per-map rows kept for the next run


def test_table3_says_what_it_covers_and_sets_the_paper_beside_the_paper_scenario_only(tmp_path):
    """A walls evaluation with two of its three cells run: its tables name the scenario, the seed and the missing
    cell, and no row stands beside the paper's open-grid numbers."""
    from tests.test_evaluate import _evaluate

    _evaluate(tmp_path / "walls", "scenario=walls", "shard=0", "num_shards=2")
    out = _script("table3.py", str(tmp_path / "walls"), "--out", str(tmp_path / "t3"))
    assert out.returncode == 0, out.stderr[-3000:]
    table = pd.read_csv(tmp_path / "t3" / "table3.csv")
    assert table["paper"].isna().all() and (table["scenario"] != "paper").all()
    head = (tmp_path / "t3" / "table3.md").read_text().splitlines()[1]
    assert f"scenario {table['scenario'][0]}, seed 7000000" in head and "2 of 3 cells; missing n20_N2" in head


def test_notebooks_take_folders_and_out_as_arguments(fixture_dirs, tmp_path):
    """`python analysis/<script>.py [DIR ...] [--out DIR]`, and missed_targets' --cells/--label/--out before its
    Hydra overrides; the environment variables are only the fallback (test_notebook_runs_on_the_fixture)."""
    surfing, coverage = fixture_dirs / "eval" / "surfing", fixture_dirs / "eval" / "coverage"
    out = _script("table3.py", str(surfing), str(coverage), "--out", str(tmp_path / "t3"))
    assert out.returncode == 0, out.stderr[-3000:]
    assert set(pd.read_csv(tmp_path / "t3" / "table3.csv").controller) == {"surfing", "coverage"}
    out = _script("compare.py", str(coverage), str(surfing), "--out", str(tmp_path / "cmp"))
    assert out.returncode == 0, out.stderr[-3000:]
    assert set(pd.read_csv(tmp_path / "cmp" / "compare.csv").baseline) == {"surfing"}
    out = _script("compare.py", str(coverage), str(surfing), "--unsaturated-by", "surfing", "--out", str(tmp_path))
    assert out.returncode == 0, out.stderr[-3000:]
    compared = pd.read_csv(tmp_path / "compare.csv")
    surfing_found = load(surfing).groupby(["n", "N"]).found_fraction.mean()
    expected = [surfing_found[(n, agents)] < 0.95 for n, agents in zip(compared.n, compared.N, strict=True)]
    assert list(compared.unsaturated) == expected and 0 < sum(expected) < len(expected)  # the fixture has both
    text = (tmp_path / "compare.md").read_text()
    assert "- where surfing finds < 0.95: " in text and f"of {sum(expected)} cells" in text
    assert "- where surfing finds >= 0.95: " in text and f"of {len(expected) - sum(expected)} cells" in text
    out = _script("compare.py", str(coverage), str(surfing), "--unsaturated-by", "teacher", "--out", str(tmp_path))
    assert out.returncode == 1 and "--unsaturated-by 'teacher' is not allowed: one of the folders' names" in out.stderr
    out = _script("compare.py", str(coverage), str(surfing), "--metric", "F", "--out", str(tmp_path / "f"))
    assert out.returncode == 0, out.stderr[-3000:]
    pairs = pd.read_csv(tmp_path / "f" / "compare.csv")
    surfing_f = load(surfing).groupby(["n", "N", "map_seed"]).F.mean().groupby(["n", "N"]).mean()
    np.testing.assert_allclose(pairs.base, [surfing_f[(n, a)] for n, a in zip(pairs.n, pairs.N, strict=True)])
    assert "saturated" not in set(pairs.verdict) and "F (better: higher)" in (tmp_path / "f" / "compare.md").read_text()
    out = _script("training_curves.py", str(fixture_dirs / "run"), "--out", str(tmp_path / "tc"))
    assert out.returncode == 0 and (tmp_path / "tc" / "training_curves.png").exists(), out.stderr[-3000:]
    out = _script("missed_targets.py", "--cells", "n20_N1", "--label", "tiny", "--out", str(tmp_path / "mt"),
                  "controller=greedy_target", "grid.maps_per_cell=2", "grid.repeats=1")  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    rows = pd.read_csv(tmp_path / "mt" / "tiny.csv")
    assert list(rows.cell) == ["n20_N1"] and list(rows.controller) == ["tiny"] and (rows.episodes == 2).all()


def test_a_missing_or_empty_folder_is_named_in_one_line(tmp_path):
    empty = tmp_path / "empty"
    (empty / "cells").mkdir(parents=True)
    damaged = tmp_path / "damaged"
    (damaged / "cells").mkdir(parents=True)
    (damaged / "cells" / "n20_N1.parquet").write_bytes(b"PAR1 not a parquet file")
    for notebook, args, message in [
        ("table3.py", [str(damaged)], f"{damaged / 'cells' / 'n20_N1.parquet'} cannot be read as a cell's results"),
        ("table3.py", [str(tmp_path / "nowhere")], f"evaluation folder '{tmp_path / 'nowhere'}' does not exist"),
        ("figures.py", [str(empty)], f"evaluation folder '{empty}' holds no results"),
        ("claims.py", [str(empty), "--out", str(tmp_path)], f"evaluation folder '{empty}' holds no results"),
        ("compare.py", [str(empty)], "1 evaluation folders given, 2 or more needed"),
        ("training_curves.py", [str(empty)], f"run folder '{empty}' has no progress.csv"),
        ("table3.py", ["--outt=x"], "unrecognized arguments: --outt=x"),
        ("missed_targets.py", ["controller=planner"], "Could not find 'controller/planner'"),
        ("missed_targets.py", ["--cells", "n7_N1"], "--cells has ['n7_N1']: not cells of the grid"),
        ("sweep.py", [str(empty)], f"{empty} holds no sweep jobs"),
    ]:
        out = _script(notebook, *args)
        assert out.returncode in (1, 2) and message in out.stderr, (notebook, out.stderr[-2000:])
        assert "Traceback" not in out.stderr and len(out.stderr.strip().splitlines()) <= 15, out.stderr


def test_a_jupyter_kernels_flags_are_not_taken_for_folders(tmp_path, monkeypatch):
    """In a notebook argv holds the kernel's flags: they are dropped and the environment variables are read."""
    from searchrl.reporting import cli

    kernel = ["-f", "/run/user/kernel-1.json", "--HistoryManager.hist_file=:memory:"]
    args, rest = cli.parse(cli.parser("x"), kernel)
    assert args.dirs == [] and args.out is None and rest == []
    monkeypatch.setenv("SEARCHRL_EVAL_DIRS", "a,b")
    monkeypatch.setenv("SEARCHRL_ANALYSIS_OUT", str(tmp_path))
    assert cli.folders(args.dirs, "SEARCHRL_EVAL_DIRS", list) == [Path("a"), Path("b")]
    assert cli.out_dir(args.out, Path("default")) == tmp_path
    args, _ = cli.parse(cli.parser("x"), ["c", "d", "--out", "o", *kernel])
    assert cli.folders(args.dirs, "SEARCHRL_EVAL_DIRS", list) == [Path("c"), Path("d")]
    assert cli.out_dir(args.out, Path("default")) == Path("o")
    monkeypatch.delenv("SEARCHRL_EVAL_DIRS")
    monkeypatch.delenv("SEARCHRL_ANALYSIS_OUT")
    assert cli.folders([], "SEARCHRL_EVAL_DIRS", lambda: [Path("default")]) == [Path("default")]
    assert cli.out_dir(None, Path("default")) == Path("default")
    parser = cli.parser("x", dirs=None)
    _, overrides = cli.parse(parser, ["controller=greedy", "+model=c", *kernel], rest=True)
    assert overrides == ["controller=greedy", "+model=c"]


def test_claims_compares_the_models_with_each_other(fixture_dirs, tmp_path):
    """The fixture policy relabelled as models b, c and diagonal: claims 2-4 run, and identical policies differ by
    exactly 0 on every cell."""
    eval_dirs = [fixture_dirs / "eval" / "surfing", fixture_dirs / "eval" / "coverage"]
    for model in ("b", "c", "diagonal"):
        cells = tmp_path / "eval" / model / "cells"
        cells.mkdir(parents=True)
        for path in (fixture_dirs / "eval" / "policy" / "cells").glob("*.parquet"):
            pd.read_parquet(path).assign(model=model, controller=f"policy:{model}").to_parquet(cells / path.name)
        eval_dirs.append(cells.parent)
    # Surfing "in C's world": the B-world surfing episodes relabelled, so policy:c − surfing (c) must equal
    # policy:b − surfing on every cell.
    cells = tmp_path / "eval" / "surfing_c" / "cells"
    cells.mkdir(parents=True)
    for path in (fixture_dirs / "eval" / "surfing" / "cells").glob("*.parquet"):
        pd.read_parquet(path).assign(model="c").to_parquet(cells / path.name)
    eval_dirs.append(cells.parent)
    _run_notebook("claims.py", eval_dirs, fixture_dirs / "run", tmp_path)
    claims = (tmp_path / "claims.md").read_text()
    for section in (
        "## 2. B beats C",
        "## 1b. DRL beats information surfing in the policy's own world",
        "## 3. Diagonal is best",
        "## 4. Communication helps most at large N",
        "Neighbours per agent per step",
        "Model with the highest mean found fraction per cell",
    ):
        assert section in claims, section
    margins = pd.read_csv(tmp_path / "margins.csv")
    between_models = margins[margins.baseline.str.startswith("policy:")]
    assert set(zip(between_models.controller, between_models.baseline, strict=True)) == {
        ("policy:b", "policy:c"), ("policy:diagonal", "policy:b"), ("policy:diagonal", "policy:c")}  # fmt: skip
    assert (between_models["diff"] == 0).all() and len(between_models) == 3 * 4
    own_world = margins[margins.baseline == "surfing (c)"].set_index(["n", "N"])
    b_world = margins[(margins.controller == "policy:b") & (margins.baseline == "surfing")].set_index(["n", "N"])
    assert set(own_world.controller) == {"policy:c"} and len(own_world) == 4
    assert (own_world["diff"] == b_world["diff"]).all()


@pytest.mark.parametrize("notebook", [p.name for p in NOTEBOOKS])
def test_notebooks_open_as_jupyter_notebooks(notebook):
    nb = jupytext.read(ROOT / "analysis" / notebook)
    kinds = {cell.cell_type for cell in nb.cells}
    assert kinds == {"markdown", "code"} and len(nb.cells) >= 4


def test_bootstrap_ci_covers_the_mean_and_shrinks_with_more_maps():
    rng = np.random.default_rng(0)
    small = bootstrap_mean_ci(rng.random(10))
    large = bootstrap_mean_ci(rng.random(1000))
    for mean, low, high in (small, large):
        assert low <= mean <= high
    assert large[2] - large[1] < small[2] - small[1]
    assert bootstrap_mean_ci(np.full(5, 0.3))[1:] == pytest.approx((0.3, 0.3))


def test_summary_averages_repeats_before_bootstrapping_maps():
    episodes = pd.DataFrame({
        "controller": "x", "model": "b", "n": 20, "N": 1, "map_seed": [1, 1, 2, 2],
        "found_fraction": [0.0, 1.0, 1.0, 1.0],
    })  # fmt: skip
    row = summarize(episodes).iloc[0]
    assert row["mean"] == pytest.approx(0.75) and row["maps"] == 2
    assert row["low"] == pytest.approx(0.5) and row["high"] == pytest.approx(1.0)


def test_paper_table_and_layouts():
    paper = paper_table3(ROOT / "analysis" / "paper_table3.csv")
    assert (
        len(paper) == 4 * 30 and paper.query("model == 'B' and n == 160 and N == 256").found_fraction.item() == 0.9878
    )
    ours = pd.DataFrame({"controller": "x", "model": "b", "n": [160], "N": [256], "mean": [0.9], "low": [0.8],
                         "high": [1.0], "maps": [3]})  # fmt: skip
    merged = beside_paper(ours, paper)
    assert merged["paper"].item() == 0.9878 and merged["diff"].item() == pytest.approx(0.9 - 0.9878)
    md = markdown(table3(ours))
    assert md.splitlines()[0].startswith("| controller | model | N | 160") and "0.900" in md


def test_render_writes_an_episode_gif(tmp_path):
    out = tmp_path / "episode.gif"
    assert render_main(["--controller", "coverage", "--n", "12", "--agents", "3", "--targets", "2",
                        "--distributions", "4", "--cell", "3", "--out", str(out)]) == 0  # fmt: skip
    gif = Image.open(out)
    assert 2 <= gif.n_frames <= 257 and gif.size[0] > 2 * gif.size[1] - 40
    with pytest.raises(SystemExit):
        render_main(["--out", str(tmp_path / "x.mp4")])


def test_a_render_says_what_plays_where_and_what_each_colour_means(tmp_path, monkeypatch):
    from PIL import ImageDraw

    drawn: list[str] = []
    original = ImageDraw.ImageDraw.text
    monkeypatch.setattr(ImageDraw.ImageDraw, "text", lambda self, xy, text, *a, **k: drawn.append(text)
                        or original(self, xy, text, *a, **k))  # fmt: skip
    args = ["--controller", "coverage", "--scenario", "walls", "--n", "20", "--agents", "2", "--targets", "2",
            "--distributions", "4", "--agent", "1", "--out", str(tmp_path / "w.gif")]  # fmt: skip
    assert render_main(args) == 0
    first = drawn[: drawn.index("uncertainty") + 1]  # the first frame's words
    assert first[0].startswith("coverage, scenario iid0.2c, 20x20, N = 2   t = 0, found 0 of 2 targets")
    assert first[1:3] == ["true world", "belief of agent 1 (ringed)"]
    assert first[3:] == ["agent", "hidden target", "found target", "wall", "probability", "uncertainty"]


def test_render_names_a_bad_size_by_its_flag(tmp_path, capsys):
    for flag, value in (("--n", "4"), ("--targets", "0")):
        with pytest.raises(SystemExit):
            render_main([flag, value, "--out", str(tmp_path / "x.gif")])
        assert f"error: {flag}={value} " in capsys.readouterr().err
    assert not (tmp_path / "x.gif").exists()


def test_paired_margins_compare_the_same_maps():
    cell = {"model": "b", "n": 40, "N": 4}
    rows = []
    for seed, (a, b) in enumerate([(1.0, 0.5), (0.75, 0.5), (1.0, 0.75)]):
        for _ in range(2):  # repeats
            rows += [{**cell, "controller": "x", "map_seed": seed, "found_fraction": a},
                     {**cell, "controller": "y", "map_seed": seed, "found_fraction": b}]  # fmt: skip
    rows.append({**cell, "controller": "y", "map_seed": 99, "found_fraction": 0.0})  # unpaired: ignored
    margins = paired_margins(pd.DataFrame(rows), "x", "y", min_maps=3)
    (row,) = margins.itertuples()
    assert row.maps == 3 and row.diff == pytest.approx(1 / 3) and row.low > 0 and row.verdict == "better"
    swapped = paired_margins(pd.DataFrame(rows), "y", "x", min_maps=3)
    assert swapped.verdict.item() == "worse" and swapped["diff"].item() == pytest.approx(-1 / 3)
    assert paired_margins(pd.DataFrame(rows), "x", "y").verdict.item() == "too few maps"  # default min_maps=20
    with pytest.raises(ValueError, match="'z'"):
        paired_margins(pd.DataFrame(rows), "x", "z")
    other_model = pd.DataFrame([*rows, {**cell, "model": "a", "controller": "y", "map_seed": 0, "found_fraction": 1}])
    with pytest.raises(ValueError, match="several models"):
        paired_margins(other_model, "x", "y")
    other_maps = pd.DataFrame(rows).assign(map_seed=lambda f: f.map_seed + (f.controller == "y") * 1000)
    with pytest.raises(ValueError, match="share no map"):
        paired_margins(other_maps, "x", "y")


def test_training_curves_carry_the_teacher_distance_and_the_critic(tmp_path):
    """A teacher-term run's cross-entropy toward its teacher and explained variance reach the tidy frame;
    analysis/training_curves.py tabulates them (teacher_distance.md) where a run logged them."""
    run = tmp_path / "term"
    run.mkdir()
    log = {"time/total_timesteps": [0, 100_000, 300_000], "val/found_fraction": [0.7, np.nan, 0.75],
           "train/imitation_loss": [np.nan, 0.2, 0.4], "train/explained_variance": [np.nan, 0.3, 0.5],
           "train/value_loss": [np.nan, 1.0, 2.0]}  # fmt: skip
    pd.DataFrame(log).to_csv(run / "progress.csv", index=False)
    curves = training_curves([run])
    assert set(curves.metric) == {"val/found_fraction", "train/imitation_loss", "train/explained_variance"}
    out = _script("training_curves.py", str(run), "--out", str(tmp_path / "tc"))
    assert out.returncode == 0, out.stderr[-3000:]
    table = (tmp_path / "tc" / "teacher_distance.md").read_text()
    assert "| 0 | 0.200 |" in table and "| 250000 | 0.400 |" in table


def test_training_curves_draw_the_seeds_of_one_setting_as_a_band_and_a_random_walk_per_model(tmp_path):
    """Three runs: two seeds of one setting (configs equal but for the seed) and another model's run. The two
    seeds become one setting with a band from their lowest to their highest value (training_bands.csv); the
    third stays a line of its own; each model's random walk is its own."""
    runs = []
    for name, model, seed, level in (("b0", "b", 0, 0.6), ("b1", "b", 1, 0.7), ("a0", "a", 0, 0.5)):
        run = tmp_path / name
        run.mkdir()
        (run / "config.yaml").write_text(f"model:\n  name: {model}\nseed: {seed}\nalgo:\n  learning_rate: 0.0003\n")
        log = {"time/total_timesteps": [0, 1000, 2000], "val/found_fraction": [level, level + 0.1, level + 0.05],
               "val/random_found_fraction": [0.1 if model == "b" else 0.2] * 3}  # fmt: skip
        pd.DataFrame(log).to_csv(run / "progress.csv", index=False)
        runs.append(run)
    curves = training_curves(runs)
    settings = curves.drop_duplicates("run").set_index("run")["setting"]
    assert settings["b0"] == settings["b1"] != settings["a0"]
    out = _script("training_curves.py", *map(str, runs), "--out", str(tmp_path / "tc"))
    assert out.returncode == 0, out.stderr[-3000:]
    bands = pd.read_csv(tmp_path / "tc" / "training_bands.csv")
    found = bands[bands.metric == "val/found_fraction"]
    assert found.seeds.unique().tolist() == [2] and found.step.tolist() == [0, 1000, 2000]
    assert found["low"].round(3).tolist() == [0.6, 0.7, 0.65] and found["high"].round(3).tolist() == [0.7, 0.8, 0.75]
    assert found["mean"].round(3).tolist() == [0.65, 0.75, 0.7]


def test_two_folders_with_one_label_are_shown_apart_by_every_analysis_script(fixture_dirs, tmp_path):
    """The same controller evaluated into two folders (as greedy and greedy_target, or a clone and its RL policy,
    share a label): `load` names each by its folder instead of merging their maps under one name, so table3,
    claims and figures (which read through it) and compare (which names by folder) all show two rows."""
    import shutil

    from searchrl.evaluate.results import load

    twin = tmp_path / "surfing_again"
    shutil.copytree(fixture_dirs / "eval" / "surfing", twin)
    both = [fixture_dirs / "eval" / "surfing", twin]
    episodes = load(*both)
    assert set(episodes.controller) == {"surfing@surfing", "surfing@surfing_again"}
    assert len(episodes) == 2 * len(load(both[0]))
    same_names = tmp_path / "a" / "surfing"
    shutil.copytree(both[0], same_names)
    assert set(load(both[0], same_names).controller) == {f"surfing@{both[0]}", f"surfing@{same_names}"}
    out = _script("table3.py", *map(str, both), "--out", str(tmp_path / "t3"))
    assert out.returncode == 0 and "named apart by its folder" in out.stderr, out.stderr[-2000:]
    table = pd.read_csv(tmp_path / "t3" / "table3.csv")
    assert set(table.controller) == {"surfing@surfing", "surfing@surfing_again"}
    for script in ("claims.py", "figures.py", "compare.py"):
        out = _script(script, *map(str, both), "--out", str(tmp_path / script))
        assert out.returncode == 0, (script, out.stderr[-2000:])


def test_one_controller_in_two_scenarios_is_shown_apart(tmp_path):
    """The tables group by controller and model: a folder of the paper's scenario and one of walls are named apart."""
    from searchrl.evaluate.results import load
    from tests.test_evaluate import _evaluate

    _evaluate(tmp_path / "greedy", "controller=greedy")
    _evaluate(tmp_path / "greedy_walls", "controller=greedy", "scenario=walls")
    episodes = load(tmp_path / "greedy", tmp_path / "greedy_walls")
    assert set(episodes.controller) == {"greedy@greedy", "greedy@greedy_walls"}
    assert set(episodes.groupby("controller").scenario.unique().map(tuple)) == {("paper",), ("iid0.2c",)}


def test_a_suite_of_scenarios_is_tabulated_per_scenario(tmp_path):
    """A suite without families of prior error (obstacles): a column per scenario, the open grid first, no severity
    table, blocked and stale per scenario, and the figure's one panel."""
    from tests.test_suite import TINY, _run

    walls = {**TINY, "severities": [], "families": {}, "variance_scales": [None],
             "scenarios": [{"obstacles": {"kind": "maze", "corridor": 2, "loops": 0.1}}]}  # fmt: skip
    for controller in ("coverage", "sweep"):
        _run(tmp_path / "suite" / controller, f"controller={controller}", suite=walls)
    # One controller in a second folder (as hedged target-greedy beside target-greedy): named by its folder
    _run(tmp_path / "suite" / "sweep_again", "controller=sweep", suite=walls)
    out = _script("suite.py", str(tmp_path / "suite"), "--focus", "sweep", "--out", str(tmp_path / "out"))
    assert out.returncode == 0, out.stderr[-3000:]
    written = sorted(p.name for p in (tmp_path / "out").glob("*.*"))
    assert written == ["compare.md", "moves.md", "quality.md", "scenario.md", "suite.png", "tail.md"]
    header = (tmp_path / "out" / "scenario.md").read_text().splitlines()[2]
    assert header.startswith("| controller | open | maze2") and header.endswith("| whole suite |")
    moves = (tmp_path / "out" / "moves.md").read_text()
    assert "| coverage |" in moves and "| sweep |" in moves and "| sweep_again |" in moves
    assert "## sweep − sweep_again" in (tmp_path / "out" / "compare.md").read_text()
    # One of its two scenarios left: no "whole suite" column, and the missing scenario named
    for folder in (tmp_path / "suite").glob("*/maze*"):
        shutil.rmtree(folder)
    out = _script("suite.py", str(tmp_path / "suite"), "--out", str(tmp_path / "part"))
    assert out.returncode == 0, out.stderr[-3000:]
    lines = (tmp_path / "part" / "scenario.md").read_text().splitlines()
    assert (
        lines[2].endswith("| the 1 scenarios held |")
        and "no results for 1 of the suite's 2 scenarios (maze" in lines[0]
    )


def test_a_suite_run_part_way_is_compared_on_the_maps_all_have_and_a_missing_scenario_is_refused(tmp_path):
    """Killed part-way: a scenario's cells of one controller gone. The tables compare every controller on the maps
    all have under every scenario and say how many were left out; a controller without a whole scenario, or a
    damaged cell file, is one line before any output."""
    import shutil

    from tests.test_suite import TINY, _run

    walls = {**TINY, "severities": [], "families": {}, "variance_scales": [None],
             "scenarios": [{"obstacles": {"kind": "maze", "corridor": 2, "loops": 0.1}}]}  # fmt: skip
    for controller in ("coverage", "sweep"):
        _run(tmp_path / "suite" / controller, f"controller={controller}", suite=walls)
    maze = next(p for p in (tmp_path / "suite" / "sweep").iterdir() if p.name.startswith("maze"))
    cells = sorted((maze / "cells").glob("*.parquet"))
    assert len(cells) >= 2
    cells[0].unlink()  # the suite killed before this cell
    out = _script("suite.py", str(tmp_path / "suite"), "--out", str(tmp_path / "out"))
    assert out.returncode == 0, out.stderr[-3000:]
    header = (tmp_path / "out" / "scenario.md").read_text().splitlines()[0]
    assert "maps that not every controller and scenario has left out" in header and cells[0].stem not in header
    shutil.rmtree(maze)  # a whole scenario missing
    out = _script("suite.py", str(tmp_path / "suite"), "--out", str(tmp_path / "out2"))
    assert out.returncode == 1 and "error: sweep has no results under scenario 'maze2l0.1'" in out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "out2").exists()
    cells[1].parent.mkdir(parents=True)
    cells[1].write_bytes(b"PAR1 truncated")
    out = _script("suite.py", str(tmp_path / "suite"), "--out", str(tmp_path / "out3"))
    assert out.returncode == 1 and f"{cells[1]} cannot be read as a cell's results" in out.stderr
    assert not (tmp_path / "out3").exists()


@pytest.mark.parametrize(
    "given", ["x=runs/reference/term/b/model.zip", "x=nope.zip@0.5", "=runs/reference/term/b/model.zip@2"]
)
def test_hedging_refuses_a_bad_switch_policy_before_any_work(given, tmp_path):
    out = _script("hedging.py", "--policies-only", "--switch-policy", given, "--out", str(tmp_path / "out"))
    assert out.returncode == 2 and f"--switch-policy={given!r} is not allowed: label=path/model.zip@θ" in out.stderr
    assert not (tmp_path / "out").exists()
