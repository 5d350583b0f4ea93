"""The evaluation app on small slices of the Table 2 grid: rows, seeds, reruns, shards, checkpoints, errors."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from searchrl.evaluate.app import evaluate
from searchrl.evaluate.cell_bounds import BOUND_COLUMNS
from searchrl.evaluate.grid import table2_cells
from searchrl.evaluate.results import load
from searchrl.evaluate.runner import COLUMNS
from searchrl.multirun import exits
from searchrl.shared_schema import CONF_DIR

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
SLICE = ["grid.world_sizes=[20,40]", "grid.n_targets=[4,8]", "grid.n_distributions=[8,16]", "grid.max_agents=[2,1]",
         "grid.maps_per_cell=3", "grid.repeats=2", "progress_bar=false", "threads=1", "bound_draws=200",
         "bound_cache=null"]  # fmt: skip


def _evaluate(out: Path, *overrides: str) -> pd.DataFrame:
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="evaluate", overrides=[*SLICE, f"out_dir={out}", *overrides])
    return load(evaluate(cfg, list(overrides)))  # the command line's overrides, as Hydra gives them


def test_table2_grid_has_the_papers_30_cells():
    cells = table2_cells([20, 40, 80, 160], [4, 8, 16, 32], [8, 16, 32, 64], [32, 64, 128, 256])
    assert len(cells) == 30
    assert [c.n_agents for c in cells if c.n == 160] == [1, 2, 4, 8, 16, 32, 64, 128, 256]


@pytest.mark.parametrize("controller", ["surfing", "greedy", "coverage", "random"])
def test_slice_rows_and_rerun_skips_done_cells(tmp_path, controller, capsys):
    frame = _evaluate(tmp_path, f"controller={controller}")
    assert list(frame.columns) == COLUMNS + BOUND_COLUMNS
    per_map = frame.groupby(["n", "N", "map_seed"]).bound_fraction.nunique()
    assert (per_map == 1).all() and frame.bound_fraction.between(0, 1).all()  # one bound per map, for every repeat
    assert len(frame) == 3 * 3 * 2  # cells (20,1) (20,2) (40,1) × 3 maps × 2 repeats
    assert set(zip(frame.n, frame.N, strict=True)) == {(20, 1), (20, 2), (40, 1)}
    assert frame.found_fraction.between(0, 1).all() and frame.L.between(1, 256).all()
    assert (frame.controller == controller).all() and (frame.model == "b").all()
    # Repeats of a map share its seed and are numbered 0, 1; maps differ.
    assert (frame.groupby(["n", "N", "map_seed"]).repeat.agg(lambda r: sorted(r) == [0, 1])).all()
    files = {p: p.stat().st_mtime_ns for p in (tmp_path / "cells").iterdir()}
    printed = capsys.readouterr().out.splitlines()  # the app's table: coverage, then a row per cell with its CI
    assert printed[0].startswith(f"{frame.controller.iloc[0]}: scenario paper, seed 7000000, 3 maps x 2 repeats")
    assert printed[1].split() == ["n", "N", "maps", "found", "95%", "CI", "bound"] and len(printed) == 5
    n, agents, maps, found = printed[2].split()[:4]
    cell = frame[(frame.n == int(n)) & (frame.N == int(agents))]
    assert int(maps) == 3 and float(found) == round(cell.groupby("map_seed").found_fraction.mean().mean(), 3)
    _evaluate(tmp_path, f"controller={controller}")
    assert "0 of 3 cells to run" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "cells").iterdir()} == files


def test_same_seed_same_results_and_model_presets(tmp_path):
    a = _evaluate(tmp_path / "a", "+model=a")
    b = _evaluate(tmp_path / "b", "+model=a")
    pd.testing.assert_frame_equal(a, b)
    assert (a.model == "a").all()
    c = _evaluate(tmp_path / "c", "+model=a", "seed=123")
    assert not a.map_seed.equals(c.map_seed)


def test_shards_split_the_cells(tmp_path):
    out = tmp_path / "sharded"
    first = _evaluate(out, "shard=0", "num_shards=2")
    both = _evaluate(out, "shard=1", "num_shards=2")
    assert set(zip(first.n, first.N, strict=True)) == {(20, 1), (40, 1)}
    assert len(both) == 18
    whole = _evaluate(tmp_path / "whole")
    pd.testing.assert_frame_equal(
        both.sort_values(["n", "N", "map_seed", "repeat"]).reset_index(drop=True),
        whole.sort_values(["n", "N", "map_seed", "repeat"]).reset_index(drop=True),
    )


def test_checkpoint_settings_come_from_its_run(tmp_path, capsys):
    from tests.test_train import TINY, _run

    model = _run(tmp_path / "run", ["+model=diagonal", *TINY, "total_timesteps=256", "validation.every=0"])
    frame = _evaluate(tmp_path / "eval", f"checkpoint={model}")  # the run decides the model (+model= is refused)
    assert (frame.model == "diagonal").all() and (frame.controller == "policy:run").all()
    assert len(frame) == 18
    again = _evaluate(tmp_path / "again", f"checkpoint={model}")  # sampled actions come from the eval seed
    pd.testing.assert_frame_equal(frame, again)
    capsys.readouterr()
    with pytest.raises(SystemExit), exits():  # argmax actions are other episodes: not into the sampled ones' folder
        _evaluate(tmp_path / "again", f"checkpoint={model}", "deterministic=true")
    assert "deterministic: False there, True here" in capsys.readouterr().err
    from searchrl.policies.checkpoint import load_actor
    from searchrl.world.config import WorldConfig

    six = WorldConfig(diagonal=True, belief_age=1.0, belief_age_channel=True)  # a sixth channel it never saw
    with pytest.raises(ValueError, match=r"sees a \(5, 11, 11\) field of view but the world shows \(6, 11, 11\)"):
        load_actor(model, six)
    with zipfile.ZipFile(model, "a") as archive:  # the same path, another file (as if retrained)
        archive.writestr("note.txt", "retrained")
    with pytest.raises(SystemExit), exits():
        _evaluate(tmp_path / "again", f"checkpoint={model}")
    assert "checkpoint_sha256" in capsys.readouterr().err


def test_one_override_chooses_the_scenario_for_a_heuristic_and_a_checkpoint(tmp_path, capsys):
    """`scenario=walls` and `scenario=off_prior`: the rows name the scenario, the maps keep their priors (a map seed
    gives the same prior in every scenario) and the walls block cells; a checkpoint is evaluated under any scenario,
    and a folder of one scenario refuses another's results."""
    paper = _evaluate(tmp_path / "paper", "controller=greedy")
    walls = _evaluate(tmp_path / "walls", "controller=greedy", "scenario=walls")
    off = _evaluate(tmp_path / "off", "controller=greedy", "scenario=off_prior")
    assert (
        (paper.scenario == "paper").all()
        and (walls.scenario == "iid0.2c").all()
        and (off.scenario == "off_prior1").all()
    )
    assert (
        paper.bound.notna().all() and walls.bound.notna().all() and off.bound.isna().all()
    )  # bound needs the prior's law
    assert (paper.map_seed.to_numpy() == off.map_seed.to_numpy()).all()
    assert not paper.found_fraction.equals(off.found_fraction) and not paper.found_fraction.equals(walls.found_fraction)
    with pytest.raises(SystemExit), exits():
        _evaluate(tmp_path / "walls", "controller=greedy", "scenario=off_prior")
    assert "scenario.targets.kind: 'prior' there, 'off_prior' here" in capsys.readouterr().err
    from tests.test_train import TINY, _run

    model = _run(tmp_path / "run", ["+model=b", *TINY, "total_timesteps=256", "validation.every=0"])
    policy = _evaluate(tmp_path / "policy_walls", f"checkpoint={model}", "scenario=walls")
    assert (policy.scenario == "iid0.2c").all() and len(policy) == 18


def test_a_folder_refuses_results_of_other_settings(tmp_path, capsys):
    """Cells are skipped when their file exists, so a run with other settings must not resume another's folder."""
    first = _evaluate(tmp_path, "controller=greedy", "shard=0", "num_shards=2")
    record = (tmp_path / "evaluation.yaml").read_text()
    assert "horizon: 2" in record and "maps_per_cell: 3" in record
    changes = [("controller.horizon=1", "controller_args.horizon: 2 there, 1 here"),
               ("seed=5", "seed: 7000000 there, 5 here"), ("+model=c", "model: 'b' there, 'c' here"),
               ("grid.maps_per_cell=4", "grid.maps_per_cell: 3 there, 4 here"),
               ("grid.repeats=3", "grid.repeats: 2 there, 3 here")]  # fmt: skip
    for override, difference in changes:
        capsys.readouterr()
        with pytest.raises(SystemExit) as exit_, exits():
            _evaluate(tmp_path, "controller=greedy", "shard=1", "num_shards=2", override)
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and f"out_dir={str(tmp_path)!r} holds results of other settings" in err, err
        assert difference in err, err
    assert len(load(tmp_path)) == len(first) and (tmp_path / "evaluation.yaml").read_text() == record
    both = _evaluate(tmp_path, "controller=greedy", "shard=1", "num_shards=2", "threads=2", "batch_mb=64")
    assert len(both) == 18  # the same settings resume: threads and batch size are not recorded


def _episodes(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.sort_values(["n", "N", "map_seed", "repeat"]).reset_index(drop=True)


@pytest.mark.parametrize("controller", ["controller=greedy", "controller=surfing", "controller=random",
                                        pytest.param(f"checkpoint={ROOT / 'runs/reference/b/model.zip'}",
                                                     marks=pytest.mark.slow)])  # fmt: skip
def test_batches_threads_and_shards_change_no_episode(tmp_path, controller):
    """Each episode draws from its own streams: one world per batch on two threads in three shards plays the same
    episodes, bit for bit, as the whole cell in one batch on one thread (a sampled policy included)."""
    # a policy's one-world batches step its network once per world and step: the n = 20 cells alone keep it short
    small = ["grid.world_sizes=[20]", "grid.n_targets=[4]", "grid.n_distributions=[8]", "grid.max_agents=[2]"]
    cells = small if controller.startswith("checkpoint=") else []
    whole = _evaluate(tmp_path / "whole", controller, "batch_mb=1024", *cells)
    for shard in range(3):
        split = _evaluate(tmp_path / "split", controller, "batch_mb=0.01", "threads=2", f"shard={shard}",
                          "num_shards=3", *cells)  # fmt: skip
    pd.testing.assert_frame_equal(_episodes(whole), _episodes(split))
    # 1-3 worlds a batch: each starts the cell's next episode while the others still play theirs
    few = _evaluate(tmp_path / "few", controller, "batch_mb=0.1", *cells)
    pd.testing.assert_frame_equal(_episodes(whole), _episodes(few))
    # The repeats of a map are distinct episodes (their own streams), not one episode written twice
    first, second = (whole[whole.repeat == r].reset_index(drop=True) for r in (0, 1))
    assert (first[["L", "R"]].to_numpy() != second[["L", "R"]].to_numpy()).any()


def test_checkpoint_labels_keep_files_of_one_run_apart(tmp_path):
    from searchrl.policies.checkpoint import checkpoint_label

    run = tmp_path / "b_seed0"
    assert checkpoint_label(run / "model.zip") == "b_seed0"
    assert checkpoint_label(run / "imitation.zip") == "b_seed0@imitation"
    assert checkpoint_label(run / "checkpoints" / "step_512.zip") == "b_seed0@step_512"
    # Under a runs/ folder the label is the run's path below it: a clone and its RL policy, both run folders `b`,
    # never share a label or a default output folder (the nearest runs/ counts)
    runs = tmp_path / "runs" / "x" / "runs" / "reference"
    labels = {checkpoint_label(runs / sub / "model.zip") for sub in ("b", "term/b", "rl/b")}
    assert labels == {"reference/b", "reference/term/b", "reference/rl/b"}
    assert checkpoint_label(runs / "term" / "b" / "checkpoints" / "step_512.zip") == "reference/term/b@step_512"
    assert checkpoint_label(tmp_path / "runs" / "model.zip") == "runs"  # a run folder named runs: its own name


@pytest.mark.parametrize(
    "override, message",
    [
        ("grid.max_agents=[2]", "grid lists differ"),
        ("shard=2", "shard=2"),
        ("grid.repeats=0", "grid.repeats=0"),
        ("bound_draws=10", "bound_draws=10"),
        ("checkpoint=/nonexistent/model.zip", "does not exist"),
        ("controller.radius=-1", "radius=-1"),
        ("controller.horizon=9", "horizon=9"),
        ("controller.contested=2", "contested=2.0"),
        ("controller.w_t=-1", "w_t=-1.0"),
        ("controller.reach=-1", "reach=-1.0"),
        ("controller.age=9", "age=9.0"),
        ("scenario=walls scenario.obstacles.density=1.5", "scenario.obstacles.density=1.5 is not allowed"),
        ("threads=100000", "threads=100000 is not allowed: 1 <= threads <= 1024"),
        ("scenario=off_prior scenario.targets.severity=-1", "scenario.targets.severity=-1 is not allowed"),
        ("scenario.targets.kind=truth", "scenario.targets.kind='truth' is not allowed: one of prior, off_prior"),
        ("controller.hedge=2", "hedge=2.0"),
        ("grid.agents=[3]", "grid.agents=[3] is not allowed"),
        ("scenario=misweighted scenario.prior.severity=2", "scenario.prior.severity=2 is not allowed"),
        ("scenario=sharp scenario.prior.variance_scale=0", "scenario.prior.variance_scale=0 is not allowed"),
    ],
)
def test_bad_input_fails_before_work(tmp_path, override, message, capsys):
    overrides = override.split()
    if override.startswith("controller."):  # the controller group goes before its own settings
        overrides = ["controller=coverage" if "radius" in override else "controller=greedy", override]
    with pytest.raises(SystemExit) as exit_, exits():
        _evaluate(tmp_path, *overrides)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and message in err and "Traceback" not in err, err[-2000:]
    assert not (tmp_path / "cells").exists() and not (tmp_path / "evaluation.yaml").exists()


def test_the_command_line_names_a_bad_value_in_one_line(tmp_path):
    cmd = [sys.executable, "-m", "searchrl.evaluate", *SLICE, f"out_dir={tmp_path}", "grid.repeats=0"]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stderr.strip().splitlines()[-1].startswith("error: grid.repeats=0"), out.stderr
    assert not (tmp_path / "cells").exists()


def test_a_record_made_before_an_option_existed_resumes_at_its_default(tmp_path, capsys):
    """A folder recorded before `controller.age` and `env.world.belief_age` existed lacks them: at their defaults
    (off) the run plays the same episodes and resumes the folder; any other value is refused, naming it."""
    _evaluate(tmp_path, "controller=greedy", "shard=0", "num_shards=2")
    record = tmp_path / "evaluation.yaml"
    record.write_text("\n".join(line for line in record.read_text().splitlines() if "age:" not in line) + "\n")
    with pytest.raises(SystemExit) as exit_, exits():
        _evaluate(tmp_path, "controller=greedy", "shard=1", "num_shards=2", "controller.age=0.5")
    assert exit_.value.code == 2 and "controller_args.age: '(absent)' there, 0.5 here" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_, exits():
        _evaluate(tmp_path, "controller=greedy", "shard=1", "num_shards=2", "env.world.belief_age=0.5")
    assert exit_.value.code == 2 and "world.belief_age: '(absent)' there, 0.5 here" in capsys.readouterr().err
    assert len(_evaluate(tmp_path, "controller=greedy", "shard=1", "num_shards=2")) == 18


@pytest.mark.parametrize("budget_mb", [1024.0, 0.05])
def test_run_cell_shows_each_episode_end_once(budget_mb):
    """`on_done` sees every episode's final state exactly once, with the found targets the episode's row reports,
    whether each world plays one episode or one after another."""
    from searchrl.controllers.greedy import FootprintGreedy
    from searchrl.evaluate.runner import run_cell
    from searchrl.world.config import WorldConfig

    cell = table2_cells([20], [4], [8], [2])[1]  # n = 20, N = 2
    seen, found = [], {}

    def on_done(state, first, playing):
        seen.extend(playing[first].tolist())
        for w in np.flatnonzero(first):
            found[int(playing[w])] = state.n_found[w] / state.n_targets[w]

    frame = run_cell(lambda c, s: FootprintGreedy(c, seed=s), WorldConfig(), cell, 1, maps=3, repeats=2, seed=5,
                     budget_mb=budget_mb, needs_observation=False, on_done=on_done)  # fmt: skip
    assert sorted(seen) == list(range(6))
    assert np.allclose([found[w] for w in range(6)], frame.found_fraction)


def test_a_clone_and_its_rl_policy_default_to_folders_and_labels_of_their_own(tmp_path, monkeypatch):
    """runs/reference/b (the clone) and runs/reference/term/b (its RL policy) are both run folders `b`: each is
    evaluated into runs/eval/policy/<its path under runs/> under that label, the second not refused."""
    monkeypatch.chdir(tmp_path)  # the default out_dir is relative to the working directory
    outs = {}
    for run in ("b", "term/b"):
        checkpoint = ROOT / "runs" / "reference" / run / "model.zip"
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            cfg = compose(config_name="evaluate", overrides=[*SLICE, "grid.maps_per_cell=1", "grid.repeats=1",
                                                             f"checkpoint={checkpoint}"])  # fmt: skip
        outs[run] = evaluate(cfg, [f"checkpoint={checkpoint}"])
    assert outs == {"b": Path("runs/eval/policy/reference/b"), "term/b": Path("runs/eval/policy/reference/term/b")}
    assert set(load(outs["b"]).controller) == {"policy:reference/b"}
    assert set(load(outs["term/b"]).controller) == {"policy:reference/term/b"}


def test_greedy_target_is_greedy_with_its_settings_recorded_so(tmp_path, monkeypatch, capsys):
    """controller=greedy_target writes runs/eval/greedy_target by default, records `greedy` with horizon 3,
    w_p = w_u = 0, w_t = 1, and plays the episodes those settings spelled out play: either resumes the other's
    folder, and other settings are refused there."""
    from omegaconf import OmegaConf

    spelled = ["controller=greedy", "controller.horizon=3", "controller.w_p=0", "controller.w_u=0", "controller.w_t=1"]
    monkeypatch.chdir(tmp_path)  # the default out_dir is relative to the working directory
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="evaluate", overrides=[*SLICE, "controller=greedy_target", "shard=0", "num_shards=2"])
    out = evaluate(cfg, ["controller=greedy_target"])
    assert out == Path("runs/eval/greedy_target")
    record = OmegaConf.load(out / "evaluation.yaml")
    assert record.controller == "greedy" and record.controller_args.name == "greedy"
    assert (record.controller_args.horizon, record.controller_args.w_p, record.controller_args.w_t) == (3, 0.0, 1.0)
    resumed = _evaluate(tmp_path / out, *spelled, "shard=1", "num_shards=2")  # the settings spelled out resume it
    assert len(resumed) == 18 and (resumed.controller == "greedy").all()
    assert len(_evaluate(tmp_path / out, "controller=greedy_target")) == 18  # and the name resumes that
    fresh = _evaluate(tmp_path / "spelled", *spelled)
    key = ["n", "N", "map_seed", "repeat"]
    pd.testing.assert_frame_equal(resumed.sort_values(key).reset_index(drop=True),
                                  fresh.sort_values(key).reset_index(drop=True))  # fmt: skip
    capsys.readouterr()
    with pytest.raises(SystemExit), exits():
        _evaluate(tmp_path / out, "controller=greedy")  # footprint-greedy's defaults are other settings
    assert "controller_args.horizon: 3 there, 2 here" in capsys.readouterr().err


def test_a_damaged_cell_file_is_named_in_one_line(tmp_path):
    frame = _evaluate(tmp_path, "controller=random")
    (tmp_path / "cells" / "n20_N1.parquet").write_bytes(b"PAR1 not a parquet file")
    with pytest.raises(ValueError, match=r"n20_N1.parquet cannot be read as a cell's results \(\w+\); remove it"):
        load(tmp_path)
    assert len(frame) == 18


def test_a_bound_cache_that_cannot_be_written_is_refused_before_work_and_a_damaged_one_is_recomputed(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(SystemExit), exits():
        _evaluate(tmp_path / "out", "controller=random", f"bound_cache={blocker}/bounds")
    assert "bound_cache=" in capsys.readouterr().err and not (tmp_path / "out" / "evaluation.yaml").exists()
    cache = tmp_path / "cache"
    first = _evaluate(tmp_path / "a", "controller=random", f"bound_cache={cache}")
    for path in cache.glob("*.parquet"):
        path.write_bytes(b"damaged")
    again = _evaluate(tmp_path / "b", "controller=random", f"bound_cache={cache}")
    assert "its bounds are computed again" in capsys.readouterr().err
    pd.testing.assert_frame_equal(first, again)
    assert all(pd.read_parquet(path).shape[0] for path in cache.glob("*.parquet"))  # replaced by whole files


def test_one_cell_plays_the_grids_maps_and_pairs_with_a_baseline_on_them(tmp_path, capsys):
    """`cell=` evaluates one cell of the grid on the maps the whole grid plays there; `baseline=` prints the paired
    verdicts against another folder at the end, its difference the mean of the per-map differences."""
    grid = _evaluate(tmp_path / "grid", "controller=surfing")
    capsys.readouterr()
    one = _evaluate(tmp_path / "one", "controller=coverage", "cell=n20_N2", f"baseline={tmp_path / 'grid'}")
    assert set(zip(one.n, one.N, strict=True)) == {(20, 2)}
    there = grid[(grid.n == 20) & (grid.N == 2)]
    assert sorted(one.map_seed.unique()) == sorted(there.map_seed.unique())
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].endswith("1 of 3 cells: n20_N2")  # what it holds, not the two it lacks
    at = next(i for i, line in enumerate(printed) if line.startswith("against surfing ("))
    assert printed[at + 1].split() == ["n", "N", "maps", "mine", "baseline", "diff", "95%", "CI", "verdict"]
    n, agents, maps, mine, base, diff = printed[at + 2].split()[:6]
    ours, theirs = one.groupby("map_seed").found_fraction.mean(), there.groupby("map_seed").found_fraction.mean()
    assert (n, agents, maps) == ("20", "2", "3") and float(mine) == pytest.approx(ours.mean(), abs=5e-4)
    assert float(base) == pytest.approx(theirs.mean(), abs=5e-4)
    assert float(diff) == pytest.approx((ours - theirs).mean(), abs=5e-4)


@pytest.mark.parametrize("bad, message", [
    ("cell=n20_N3", "cell='n20_N3' is not allowed: a cell of the grid: one of n20_N1, n20_N2, n40_N1"),
    ("seed=5", "a folder of this evaluation's worlds, whose map seeds name the same maps; it differs in seed: "
               "7000000 there, 5 here"),
    ("scenario=walls", "scenario.obstacles.density: 0.0 there, 0.2 here"),
    ("grid.n_targets=[2,4]", "grid.n_targets: [4, 8] there, [2, 4] here"),
    ("env.world.k=3", "world.k: 1000.0 there, 3.0 here"),
    ("baseline=/nonexistent", "baseline='/nonexistent' is not allowed: an evaluation folder"),
])  # fmt: skip
def test_a_cell_off_the_grid_or_a_baseline_of_other_maps_is_refused_before_work(tmp_path, bad, message, capsys):
    _evaluate(tmp_path / "base", "controller=surfing", "cell=n20_N1")
    overrides = ["controller=coverage", f"baseline={tmp_path / 'base'}", *bad.split()]
    with pytest.raises(SystemExit) as exit_, exits():
        _evaluate(tmp_path / "out", *overrides)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and message in err and "Traceback" not in err, err[-2000:]
    assert not (tmp_path / "out").exists()
