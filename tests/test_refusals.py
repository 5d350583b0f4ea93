"""Typos and refused jobs, as a user meets them: a `+key` no schema knows is refused in one line naming the nearest
known key, before any file is written (Hydra adds it silently); a multirun runs every valid job past a refused one,
names the refused ones at its end and exits non-zero (searchrl/multirun.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir

from searchrl.command_line import from_recipes, import_modules
from searchrl.evaluate.app import evaluate
from searchrl.shared_schema import CONF_DIR, recipes, unknown_keys
from searchrl.train.app import train
from searchrl.train.schema import register_configs
from searchrl.world.obstacles import MazeObstacles
from tests.registries import isolated_registries
from tests.test_faults import _refused

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
SLICE = ["grid.world_sizes=[20]", "grid.n_targets=[4]", "grid.n_distributions=[8]", "grid.max_agents=[2]",
         "grid.maps_per_cell=2", "grid.repeats=1", "progress_bar=false", "threads=1"]  # fmt: skip


def _compose(app: str, overrides: list[str], hydra: bool = False):
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose(config_name=app, overrides=overrides, return_hydra_config=hydra)


def test_a_training_key_no_schema_knows_is_refused_naming_the_nearest(tmp_path, capsys):
    overrides = ["+model=b", "+total_timestep=4096", "+algo.n_step=3", "+env.world.fovv=9"]
    cfg = _compose("train", overrides)
    _refused(capsys, lambda: train(cfg, tmp_path / "run", overrides),
             "total_timestep=4096 is not allowed: no such setting (did you mean total_timesteps?)",
             "algo.n_step=3 is not allowed: no such setting (did you mean algo.n_steps?)",
             "env.world.fovv=9 is not allowed: no such setting (did you mean env.world.fov?)")  # fmt: skip
    assert not (tmp_path / "run").exists()


def test_an_evaluation_key_no_schema_knows_is_refused_naming_the_nearest(tmp_path, capsys):
    overrides = [*SLICE, "+grid.map_per_cell=50", "controller=greedy", "+controller.horizn=2", f"out_dir={tmp_path}/e"]
    cfg = _compose("evaluate", overrides)
    _refused(capsys, lambda: evaluate(cfg, overrides), "grid.map_per_cell=50 is not allowed: no such setting (did you "
             "mean grid.maps_per_cell?)", "controller.horizn=2 is not allowed")  # fmt: skip
    assert not (tmp_path / "e").exists()


def test_every_shipped_recipe_and_app_default_knows_all_its_keys():
    """No false alarm: the keys recipes and groups write (teacher_args, scenario parts, extra_teams) all pass."""
    assert recipes()
    for recipe in recipes():  # the recipe's extensions imported first, as the entry point does
        with isolated_registries("analysis"):
            import_modules(from_recipes([f"+experiment={recipe}"]))
            register_configs()
            assert unknown_keys(_compose("train", [f"+experiment={recipe}"])) == [], recipe
    for scenario in sorted(p.stem for p in (CONF_DIR / "scenario").glob("*.yaml")):
        assert unknown_keys(_compose("evaluate", [f"scenario={scenario}", "controller=greedy_target"])) == []
    cfg = _compose("train", ["+model=c", "imitation.teacher=greedy", "+imitation.teacher_args.anything=1"])
    assert unknown_keys(cfg) == []  # a teacher's arguments are the teacher's to check


@pytest.mark.parametrize("app", ["train", "evaluate"])
def test_both_apps_name_the_failed_jobs_of_a_multirun(app):
    callbacks = _compose(app, ["+model=b"] if app == "train" else [], hydra=True).hydra.callbacks
    assert callbacks.failed_jobs._target_ == "searchrl.multirun.FailedJobs"


@pytest.mark.slow  # one refusal per job, second of a kind
def test_an_evaluation_multirun_runs_every_valid_job_past_a_refused_one(tmp_path):
    cmd = [sys.executable, "-m", "searchrl.evaluate", "-m", "controller=surfing", "controller.w_p=0.5,nan,0.7", *SLICE,
           f"out_dir={tmp_path}/w" + "${controller.w_p}", f"hydra.sweep.dir={tmp_path}/sweep"]  # fmt: skip
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 1, out.stderr[-2000:]
    assert sorted(p.name for p in tmp_path.glob("w*") if any((p / "cells").glob("*.parquet"))) == ["w0.5", "w0.7"]
    summary = out.stderr[out.stderr.index("error: 1 job(s) of the multirun failed") :]
    assert "#1 [controller=surfing controller.w_p=nan" in summary and "controller.w_p=nan" in summary.splitlines()[1]


def test_walls_that_never_leave_room_are_refused_before_the_first_cell_or_file(tmp_path, capsys):
    """Connected iid walls at density 0.9 leave a few free cells: evaluation draws every map of every cell before
    the first (it used to write the n = 20 cells, then stop with a traceback), training draws each group's walls
    before its folder is written."""
    walls = ["scenario=walls", "scenario.obstacles.density=0.9"]
    grid = ["grid.world_sizes=[20,40]", "grid.max_agents=[2,4]", "grid.n_targets=[4,8]", "grid.n_distributions=[8,16]"]
    overrides = [*SLICE, *walls, *grid, f"out_dir={tmp_path}/e"]
    cfg = _compose("evaluate", overrides)
    _refused(capsys, lambda: evaluate(cfg, overrides), "grid cell", "scenario.obstacles.density=0.9 with "
             "connected=true is not allowed here")  # fmt: skip
    assert not (tmp_path / "e").exists()
    overrides = ["+model=b", *walls]
    cfg = _compose("train", overrides)
    _refused(capsys, lambda: train(cfg, tmp_path / "run", overrides), "scenario.obstacles.density=0.9")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    "obstacles, message",
    [("scenario.obstacles.corridor=16", "corridor=16 is not allowed: at most 9 in the smallest world (n=20)"),
     ("scenario.obstacles.room_size=24", "room_size=24 is not allowed: at most the smallest world's side n=20")],
)  # fmt: skip
def test_a_maze_or_rooms_as_wide_as_the_world_are_refused(tmp_path, capsys, obstacles, message):
    overrides = [*SLICE, f"scenario={'maze' if 'corridor' in obstacles else 'rooms'}", obstacles, f"out_dir={tmp_path}"]
    cfg = _compose("evaluate", overrides)
    _refused(capsys, lambda: evaluate(cfg, overrides), message)


def test_the_maze_check_counts_the_free_cells_every_maze_has():
    """With loops=0 a maze is its lattice's open squares and the openings of a spanning tree, nothing more: the
    count the check uses, exactly."""
    for n, corridor in ((20, 1), (20, 3), (37, 4), (40, 9)):
        side = (n + 1) // (corridor + 1)
        expected = side * side * corridor * corridor + (side * side - 1) * corridor
        maze = MazeObstacles(corridor=corridor, loops=0.0)
        rng = np.random.default_rng(n + corridor)
        assert {int((~maze.draw(n, rng)).sum()) for _ in range(5)} == {expected}


def test_a_run_folder_that_cannot_be_written_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    """A resume into a checkpoints/ made read-only used to fail with a traceback after its first rollout (the test
    runs as any user: os.access is what the check asks)."""
    import os

    from searchrl import atomic

    (tmp_path / "run" / "checkpoints").mkdir(parents=True)
    real = os.access
    monkeypatch.setattr(atomic.os, "access", lambda p, mode: real(p, mode) and Path(p).name != "checkpoints")
    overrides = ["+model=b", "network=small", "env.n_worlds=2", "env.world.n_agents=4", "algo.batch_size=128",
                 "total_timesteps=256", "validation.every=0", "progress_bar=false", "threads=1"]  # fmt: skip
    cfg = _compose("train", overrides)
    _refused(capsys, lambda: train(cfg, tmp_path / "run", overrides), "checkpoints' is not allowed:", "not writable")
    assert not (tmp_path / "run" / "config.yaml").exists()


def test_a_policy_evaluated_outside_its_training_scenario_is_said_so(tmp_path, capsys):
    from searchrl.evaluate.app import plan_evaluation
    from searchrl.policies.checkpoint import training_scenario
    from searchrl.world.scenario import Scenario

    walls, open_grid = ROOT / "runs/reference/walls/b/model.zip", ROOT / "runs/reference/term/b/model.zip"
    assert Scenario.from_dict(training_scenario(walls)).label.startswith("mix-")
    assert Scenario.from_dict(training_scenario(open_grid)).label == "paper"
    for checkpoint, said in ((walls, True), (open_grid, False)):
        overrides = [*SLICE, f"checkpoint={checkpoint}", f"out_dir={tmp_path}"]
        plan_evaluation(_compose("evaluate", overrides), overrides)
        err = capsys.readouterr().err
        assert ("was trained under scenario mix-" in err and "evaluated under paper" in err) == said, err
