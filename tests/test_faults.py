"""Nothing lost, nothing silent: one test per class of fault a careful user met (issue 25), each failing before its
fix. Files survive kills, folders have one owner, resume survives damage, a failed run claims nothing, no setting is
dropped without a word, bad values get one line before any work, and the PettingZoo env checks what it is given."""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from unittest import mock

import numpy as np
import pandas as pd
import pytest
import torch
from gymnasium.error import ResetNeeded
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf
from sb3_contrib import RecurrentPPO

from searchrl.atomic import hold, temporary_path
from searchrl.command_line import check_group_choices, check_jobs_compose
from searchrl.envs.parallel_env import SearchParallelEnv
from searchrl.evaluate.app import evaluate
from searchrl.evaluate.results import load
from searchrl.multirun import exits
from searchrl.policies.checkpoint import REBUILT, load_checkpoint, policy_record, run_config
from searchrl.shared_schema import CONF_DIR
from searchrl.train.app import train
from searchrl.world.config import ConfigError, WorldConfig
from tests.scripts import run_script
from tests.test_untrusted_checkpoints import SHIPPED, poisoned

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
REFERENCE_B = ROOT / "runs" / "reference" / "b"
SLICE = ["grid.world_sizes=[20]", "grid.n_targets=[4]", "grid.n_distributions=[8]", "grid.max_agents=[2]",
         "grid.maps_per_cell=2", "grid.repeats=1", "progress_bar=false", "threads=1"]  # fmt: skip
TINY = ["+model=b", "total_timesteps=2048", "env.n_worlds=2", "env.world.n_agents=4", "env.world.world_size=[12,20]",
        "env.world.n_targets=[2,4]", "env.world.n_distributions=[4,8]", "network=small", "algo.batch_size=128",
        "checkpoint_every=1024", "validation.every=0", "progress_bar=false", "threads=1",
]  # fmt: skip


def _compose(app: str, overrides: list[str]):
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose(config_name=app, overrides=overrides)


def _evaluate(out: Path, *overrides: str) -> Path:
    args = [*SLICE, f"out_dir={out}", *overrides]
    return evaluate(_compose("evaluate", args), list(overrides))


def _refused(capsys, call, *needles: str) -> str:
    """`call` exits with 2 and one `error:` line naming every needle, no traceback."""
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_, exits():
        call()
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "Traceback" not in err, err
    line = err.strip().splitlines()[-1]
    assert "error:" in line and all(n in line for n in needles), err
    return line


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    """A finished tiny run with checkpoints at 1024 and 2048 agent-steps; tests copy it before they damage it."""
    run = tmp_path_factory.mktemp("tiny") / "run"
    train(_compose("train", TINY), run, TINY)
    return run


def _copy(run: Path, to: Path) -> Path:
    shutil.copytree(run, to)
    (to / "model.zip").unlink()
    return to


# 1. Evaluation results are never corrupted by a writer's temporary.
def test_loader_and_rerun_ignore_and_clear_what_a_killed_writer_left(tmp_path):
    out = _evaluate(tmp_path / "eval")
    clean = load(out)
    cells = out / "cells"
    (cells / "n20_N2.parquet").rename(tmp_path / "n20_N2.parquet")  # as if killed while writing this cell:
    killed = cells / ".n20_N2.parquet.node7.4242.tmp"  # a partial temporary of a writer (another pid) now dead
    killed.write_bytes(b"PAR1 half a file")
    assert killed != temporary_path(cells / "n20_N2.parquet")  # not the rerun's own, which its write would replace
    shutil.copy(tmp_path / "n20_N2.parquet", cells / ".n20_N1.4242.tmp.parquet")  # a whole one, earlier naming
    assert len(load(out)) == len(clean) // 2  # no ArrowInvalid, nothing counted twice
    _evaluate(tmp_path / "eval")  # the rerun finishes the cell and clears its temporary
    pd.testing.assert_frame_equal(load(out), clean)
    assert sorted(p.name for p in cells.iterdir()) == [".n20_N1.4242.tmp.parquet", "n20_N1.parquet", "n20_N2.parquet"]


def test_a_cell_finished_by_another_job_meanwhile_is_not_run_again(tmp_path, monkeypatch):
    """The list of cells to run is made before their locks are taken: a cell another job finished in between is
    kept as that job wrote it."""
    from contextlib import contextmanager

    import searchrl.evaluate.app as app

    theirs = load(_evaluate(tmp_path / "theirs"))
    real_hold = app.hold

    @contextmanager
    def other_job_finishes_n20_N2_first(lock_file, what, wait_s=0.0):
        if "n20_N2" in str(lock_file):
            done = theirs[theirs.N == 2].assign(R=-12345.0)  # marked, to tell it from a rerun's rows
            done.to_parquet(tmp_path / "mine" / "cells" / "n20_N2.parquet")
        with real_hold(lock_file, what, wait_s):
            yield

    monkeypatch.setattr(app, "hold", other_job_finishes_n20_N2_first)
    mine = load(_evaluate(tmp_path / "mine"))
    assert (mine[mine.N == 2].R == -12345.0).all() and (mine[mine.N == 1].R != -12345.0).all()


def test_evaluation_killed_at_any_moment_resumes_to_the_same_results(tmp_path):
    args = [*SLICE, "grid.max_agents=[8]", "grid.maps_per_cell=4", "controller=greedy"]
    whole = load(_evaluate(tmp_path / "whole", *args[len(SLICE) :]))
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "searchrl.evaluate", *args, f"out_dir={out}"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not (out / "cells" / "n20_N2.parquet").exists():
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read().decode()[-2000:]
            time.sleep(0.01)
    finally:  # killed whatever happened above
        with contextlib.suppress(ProcessLookupError):  # ended already
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    pd.testing.assert_frame_equal(load(_evaluate(out, *args[len(SLICE) :])), whole)


def test_an_interrupted_evaluation_says_so_in_one_line_and_keeps_its_cells(tmp_path, capsys, monkeypatch):
    """Ctrl-C in the second cell: exit 130 (as a shell reports SIGINT), one line, the first cell kept; a rerun
    runs the rest."""
    import searchrl.evaluate.app as app

    original, calls = app.run_cell, []

    def interrupted_in_the_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(app, "run_cell", interrupted_in_the_second)
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_, exits():
        _evaluate(tmp_path / "eval")
    err = capsys.readouterr().err
    assert exit_.value.code == 130 and "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith("interrupted: the cells already written stay")
    assert len(list((tmp_path / "eval" / "cells").iterdir())) == 1
    monkeypatch.setattr(app, "run_cell", original)
    assert len(load(_evaluate(tmp_path / "eval"))) == len(load(_evaluate(tmp_path / "clean")))


# 1b. An evaluation folder is trusted by what its cells say of themselves: each records the settings it ran under.
def test_a_lost_record_is_rebuilt_from_the_cells_not_taken_from_the_next_command(tmp_path, capsys):
    out = _evaluate(tmp_path / "eval", "shard=0", "num_shards=2")  # one of the two cells
    record = (out / "evaluation.yaml").read_text()
    (out / "evaluation.yaml").unlink()
    _refused(capsys, lambda: _evaluate(out, "seed=1"), "seed: 7000000 there, 1 here")  # not other maps beside them
    assert (out / "evaluation.yaml").read_text() == record and len(list((out / "cells").iterdir())) == 1


def test_a_cell_of_other_settings_is_refused_by_the_rerun_and_the_loader(tmp_path, capsys):
    ours, other = _evaluate(tmp_path / "ours", "shard=0", "num_shards=2"), _evaluate(tmp_path / "other", "seed=1")
    stray = sorted((other / "cells").iterdir())[1]  # the cell `ours` has not run, from seed 1's maps
    shutil.copy(stray, ours / "cells" / stray.name)
    _refused(capsys, lambda: _evaluate(ours), f"cells/{stray.name} holds results of other settings", "seed: 1 there")
    with pytest.raises(ValueError, match=r"hold results of other settings .*seed"):
        load(ours)


def test_a_damaged_cell_is_set_aside_and_run_again(tmp_path, capsys):
    out = _evaluate(tmp_path / "eval")
    clean = load(out)
    cell = sorted((out / "cells").iterdir())[0]
    cell.write_bytes(cell.read_bytes()[:100])  # a broken copy
    _evaluate(out)
    assert f"set aside as {cell.name}.unreadable" in capsys.readouterr().err
    pd.testing.assert_frame_equal(load(out), clean)


# Each way a file can be damaged: (name, damage(path, the same file of another folder)).
DAMAGES = {
    "deleted": lambda path, other: path.unlink(),
    "truncated": lambda path, other: path.write_bytes(path.read_bytes()[: path.stat().st_size // 2]),
    "garbage": lambda path, other: path.write_bytes(b"\x00\xffnot this file" * 9),
    "swapped": lambda path, other: shutil.copy(other, path),  # another evaluation's (seed 1) file of that name
}


def _damaged_copies(clean: Path, other: Path, files: list[Path], to: Path):
    """(file, damage, folder) for each file of `clean` and each of DAMAGES in turn: `folder` a copy of `clean` with
    that file so damaged (swapped for `other`'s file of that name)."""
    for rel in files:
        for name, damage in DAMAGES.items():
            folder = to / f"{rel.name}_{name}"
            shutil.copytree(clean, folder)
            damage(folder / rel, other / rel)
            yield rel, name, folder


def _rerun(capsys, call) -> str:
    """'repaired' when `call` runs to its end, 'refused' when it exits 2 with one error line and no traceback."""
    capsys.readouterr()
    try:
        with exits():
            call()
        return "repaired"
    except SystemExit as stop:
        err = capsys.readouterr().err
        assert stop.code == 2 and "Traceback" not in err and err.strip().splitlines()[-1].startswith("error:"), err
        return "refused"


def test_an_evaluation_folder_repairs_or_refuses_each_damaged_file_and_loses_nothing(tmp_path, capsys):
    """Each file of a finished evaluation folder in turn deleted, truncated, overwritten or swapped for another
    evaluation's: the rerun repairs it (the folder's results then equal the undamaged ones) or refuses in one line;
    either way every other file is still there as it was, and no loader mixes the two evaluations."""
    clean, other = _evaluate(tmp_path / "clean"), _evaluate(tmp_path / "other", "seed=1")
    want = load(clean)
    files = sorted(p.relative_to(clean) for p in clean.rglob("*") if p.is_file() and ".locks" not in p.parts)
    outcomes = {}
    for rel, name, folder in _damaged_copies(clean, other, files, tmp_path / "damaged"):
        kept = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file() and p != folder / rel}
        outcome = outcomes[f"{rel.name} {name}"] = _rerun(capsys, lambda f=folder: _evaluate(f))
        assert all(p.read_bytes() == content for p, content in kept.items() if ".locks" not in p.parts)
        if outcome == "repaired":
            pd.testing.assert_frame_equal(load(folder), want)
    cells = [rel.name for rel in files if rel.suffix == ".parquet"]
    assert outcomes == {
        **{f"evaluation.yaml {name}": "repaired" for name in ("deleted", "truncated", "garbage")},
        "evaluation.yaml swapped": "refused",  # seed 1's record over seed 7000000's cells: which is right is unsaid
        **{f"{cell} {name}": "repaired" for cell in cells for name in ("deleted", "truncated", "garbage")},
        **{f"{cell} swapped": "refused" for cell in cells},  # another evaluation's cell: never mixed in
    }


@pytest.mark.slow  # 28 resumes, about two minutes; the checkpoint cases are also tests of their own above
def test_a_training_run_repairs_or_refuses_each_damaged_file_and_loses_nothing(tmp_path, tiny_run, capsys):
    """Each file of a finished tiny run in turn deleted, truncated, overwritten or swapped for another run's (seed
    1), then resumed one rollout further: the resume repairs it (a run that continues: its model at the new budget,
    each step logged once, beside a segment's final validation) or refuses in one line, and a refused resume leaves
    every file as it was."""
    other = tmp_path / "other"
    train(_compose("train", [*TINY, "seed=1"]), other, [*TINY, "seed=1"])
    files = sorted(p.relative_to(tiny_run) for p in tiny_run.rglob("*") if p.is_file() and p.name != ".lock"
                   and p.parent.name != "tensorboard")  # fmt: skip
    outcomes = {}
    for rel, name, run in _damaged_copies(tiny_run, other, files, tmp_path / "damaged"):
        before = _files(run)
        overrides = [f"resume={run}", "total_timesteps=2304"]
        outcome = outcomes[f"{rel.name} {name}"] = _rerun(
            capsys, lambda o=overrides, r=run: train(_compose("train", o), r / "r", o)
        )
        if outcome == "refused":
            assert _files(run) == before
        else:
            steps = pd.read_csv(run / "progress.csv")["time/total_timesteps"]
            assert load_checkpoint(run / "model.zip").num_timesteps == 2304 and steps.iloc[-1] == 2304
            assert steps.is_monotonic_increasing and steps.value_counts().max() <= 2  # + a final validation
    refused = sorted(k for k, v in outcomes.items() if v == "refused")
    print(outcomes)
    assert refused == sorted([*(f"config.yaml {n}" for n in DAMAGES), *(f"progress.csv {n}" for n in DAMAGES),
                              "step_2048.zip swapped"]), outcomes  # a deleted log: its checkpoint saw rows  # fmt: skip


# 2. A run folder has one owner.
def test_a_run_folder_in_use_is_refused(tmp_path, tiny_run, capsys):
    run = _copy(tiny_run, tmp_path / "run")
    files = lambda: {p.name: p.read_bytes() for p in run.iterdir() if p.is_file() and p.name != ".lock"}  # noqa: E731
    before = files()
    overrides = [f"resume={run}", "total_timesteps=4096"]
    with hold(run / ".lock", "the test's run"):  # as a first resume of it would, still running
        _refused(capsys, lambda: train(_compose("train", overrides), run / "resumed", overrides), "is in use by")
        _refused(capsys, lambda: train(_compose("train", TINY), run, TINY), "is in use by")
    assert files() == before
    _refused(capsys, lambda: train(_compose("train", TINY), run, TINY), "already holds a run", f"resume={run}")


# 3. Resume survives a damaged newest checkpoint, a small budget and killed temporaries.
def test_resume_falls_back_from_a_truncated_checkpoint_and_clears_temporaries(tmp_path, tiny_run, capsys):
    run = _copy(tiny_run, tmp_path / "run")
    newest = run / "checkpoints" / "step_2048.zip"
    newest.write_bytes(newest.read_bytes()[: newest.stat().st_size // 2])
    killed = [temporary_path(run / "checkpoints" / "step_3072.zip"), run / "checkpoints" / ".step_3072.77.tmp.zip"]
    for path in killed:
        path.write_bytes(b"half")
    with open(run / "progress.csv", "a") as f:
        f.write("0.5,12")  # a row cut short by the kill
    overrides = [f"resume={run}", "total_timesteps=1536"]
    final = train(_compose("train", overrides), run / "resumed", overrides)
    assert "step_2048.zip" in capsys.readouterr().err and (run / "checkpoints" / "step_2048.zip.unreadable").exists()
    assert RecurrentPPO.load(final).num_timesteps == 1536
    assert not any(path.exists() for path in killed)
    # each step once (rows past the checkpoint dropped, then logged again), and the final model's validation
    assert pd.read_csv(run / "progress.csv")["time/total_timesteps"].tolist() == [*range(256, 1537, 256), 1536]


def test_a_checkpoint_that_cannot_be_read_now_is_not_taken_for_a_damaged_one(tmp_path, tiny_run, capsys, monkeypatch):
    """A passing read fault (no permission, as on a flaky network file system) refuses the resume in one line and
    renames nothing; with access back, the resume continues from the newest checkpoint."""
    import zipfile

    run = _copy(tiny_run, tmp_path / "run")
    before = sorted(p.name for p in (run / "checkpoints").iterdir())
    original = zipfile.ZipFile

    def no_access(file, *args, **kwargs):
        name = str(getattr(file, "name", file))  # SB3 opens the file first and passes the open file
        if name.endswith(".zip") and "checkpoints" in name:
            raise PermissionError(13, "Permission denied", name)
        return original(file, *args, **kwargs)

    monkeypatch.setattr(zipfile, "ZipFile", no_access)
    overrides = [f"resume={run}", "total_timesteps=2304"]
    _refused(capsys, lambda: train(_compose("train", overrides), run / "resumed", overrides),
             "step_2048.zip cannot be read now (PermissionError: Permission denied); nothing was renamed")  # fmt: skip
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == before
    monkeypatch.setattr(zipfile, "ZipFile", original)
    final = train(_compose("train", overrides), run / "resumed2", overrides)
    assert "resuming" in capsys.readouterr().err and RecurrentPPO.load(final).num_timesteps == 2304


def test_resume_that_cannot_start_leaves_the_run_as_it_was(tmp_path, tiny_run, capsys):
    run = _copy(tiny_run, tmp_path / "run")
    record = (run / "config.yaml").read_bytes()
    overrides = [f"resume={run}", "total_timesteps=1024"]  # below the 2048 agent-steps it has trained
    _refused(capsys, lambda: train(_compose("train", overrides), run / "r", overrides), "total_timesteps=1024", "2048")
    for path in (run / "checkpoints").glob("step_*.zip"):
        path.write_bytes(b"not a zip")
    overrides = [f"resume={run}", "total_timesteps=9999"]
    _refused(capsys, lambda: train(_compose("train", overrides), run / "r", overrides), "no checkpoint", "be read")
    assert (run / "config.yaml").read_bytes() == record and not (run / "model.zip").exists()


def test_a_finished_run_without_checkpoints_is_not_trained_over(tmp_path, tiny_run, capsys):
    """A shipped folder (model.zip, no checkpoints/) is refused on resume, not restarted over its model."""
    run = tmp_path / "shipped"
    shutil.copytree(tiny_run, run)
    shutil.rmtree(run / "checkpoints")
    model = (run / "model.zip").read_bytes()
    overrides = [f"resume={run}", "total_timesteps=4096"]
    _refused(capsys, lambda: train(_compose("train", overrides), run / "r", overrides), "finished run", "init=")
    assert (run / "model.zip").read_bytes() == model


def test_a_run_killed_before_its_first_checkpoint_starts_again_from_its_init(tmp_path, tiny_run, capsys):
    """Its restart takes the weights of `init=` again (a file that does not fit is named, so it was read)."""
    run = _copy(tiny_run, tmp_path / "run")
    shutil.rmtree(run / "checkpoints")
    (tmp_path / "other.zip").write_bytes(b"not a zip")
    config = OmegaConf.load(run / "config.yaml")
    config.init = str(tmp_path / "other.zip")
    (run / "config.yaml").write_text(OmegaConf.to_yaml(config))
    overrides = [f"resume={run}"]
    _refused(capsys, lambda: train(_compose("train", overrides), run / "r", overrides), "init=", "does not fit")


# 3b. A model.zip from anyone runs no code: its pickled entries are rebuilt, its tensors read as weights only.
def test_the_apps_load_a_zip_with_every_entry_poisoned_and_run_none(tmp_path, tiny_run, capsys):
    """evaluate, render, init= and resume= on zips whose every pickled entry is a payload: each runs to its end."""
    from searchrl.render import main as render

    marker = tmp_path / "ran"
    every = tuple(REBUILT)
    shipped = poisoned(SHIPPED, tmp_path / "shipped", marker, entries=every)
    _evaluate(tmp_path / "eval", f"checkpoint={shipped}")
    assert (tmp_path / "eval" / "evaluation.yaml").exists()
    render(["--checkpoint", str(shipped), "--n", "20", "--agents", "2", "--out", str(tmp_path / "episode.gif")])
    assert (tmp_path / "episode.gif").stat().st_size > 0

    init = poisoned(tiny_run, tmp_path / "tiny", marker, entries=every)
    overrides = [*TINY, f"init={init}", "total_timesteps=256"]
    assert train(_compose("train", overrides), tmp_path / "init", overrides).exists()
    shutil.rmtree(tmp_path / "tiny")
    run = tmp_path / "tiny"
    poisoned(tiny_run, run, marker, entries=every, name="checkpoints/step_2048.zip")
    (run / "model.zip").unlink()  # as if killed after its last checkpoint
    overrides = [f"resume={run}", "total_timesteps=2304"]
    final = train(_compose("train", overrides), run / "r", overrides)
    assert "resuming" in capsys.readouterr().err and load_checkpoint(final).num_timesteps == 2304
    assert not marker.exists()


def test_the_apps_refuse_a_poisoned_tensor_file_in_one_line(tmp_path, tiny_run, capsys):
    from searchrl.render import main as render

    marker = tmp_path / "ran"
    shipped = poisoned(SHIPPED, tmp_path / "shipped", marker, tensor="policy.pth")
    _refused(capsys, lambda: _evaluate(tmp_path / "eval", f"checkpoint={shipped}"), "Weights only load failed")
    _refused(capsys, lambda: render(["--checkpoint", str(shipped), "--out", str(tmp_path / "x.gif")]), "Weights only")
    init = poisoned(tiny_run, tmp_path / "tiny", marker, tensor="policy.pth")
    overrides = [*TINY, f"init={init}"]
    _refused(capsys, lambda: train(_compose("train", overrides), tmp_path / "init", overrides), "init=", "Weights")
    assert not marker.exists()


# 3c. A run folder is trusted by what its files say of themselves, not by their names.
def _rewrite_identity(path: Path, change) -> None:
    """Apply `change` to the run settings a checkpoint's searchrl.json records, every other member kept."""
    import json
    import zipfile

    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    identity = json.loads(members["searchrl.json"])
    change(identity["run"])
    members["searchrl.json"] = json.dumps(identity).encode()
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)


def _files(run: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(run)): p.read_bytes() for p in sorted(run.rglob("*")) if p.is_file() and p.name != ".lock"
    }


def test_resume_refuses_a_checkpoint_of_another_run_or_step_and_changes_nothing(tmp_path, tiny_run, capsys):
    """A checkpoint copied in under another step's name, one saved by a run of another model, a config.yaml edited
    since (another LSTM width) and a log that is not the checkpoint's are each refused in one line naming both
    sides; no file changes."""
    run = _copy(tiny_run, tmp_path / "run")
    overrides = [f"resume={run}", "total_timesteps=4096"]
    resume = lambda: train(_compose("train", overrides), run / "r", overrides)  # noqa: E731
    shutil.copy(run / "checkpoints" / "step_1024.zip", run / "checkpoints" / "step_3072.zip")
    before = _files(run)
    _refused(capsys, resume, "checkpoints/step_3072.zip holds a model saved at step 1024, not 3072")
    assert _files(run) == before
    (run / "checkpoints" / "step_3072.zip").unlink()

    _rewrite_identity(run / "checkpoints" / "step_2048.zip", lambda r: r["model"].update(name="a"))
    before = _files(run)
    _refused(capsys, resume, "step_2048.zip was saved by a run with model.name='a'", "config.yaml says model.name='b'")
    assert _files(run) == before

    shutil.rmtree(run)
    run = _copy(tiny_run, tmp_path / "run")
    config = OmegaConf.load(run / "config.yaml")
    config.network.lstm_hidden_size = 256
    (run / "config.yaml").write_text(OmegaConf.to_yaml(config))
    before = _files(run)
    _refused(capsys, resume, "network.lstm_hidden_size=128", "config.yaml says network.lstm_hidden_size=256")
    assert _files(run) == before

    shutil.rmtree(run)  # a log edited (or another run's put in its place): its rows are not the checkpoint's
    run = _copy(tiny_run, tmp_path / "run")
    log = pd.read_csv(run / "progress.csv")
    log.loc[1, "time/fps"] += 1
    log.to_csv(run / "progress.csv", index=False)
    before = _files(run)
    _refused(capsys, resume, "progress.csv is not the log checkpoints/step_2048.zip was saved with")
    assert _files(run) == before


def test_a_resume_with_nothing_to_do_changes_no_file(tmp_path, tiny_run, capsys):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    before = _files(run)
    overrides = [f"resume={run}", "total_timesteps=2048"]
    assert train(_compose("train", overrides), run / "r", overrides) == run / "model.zip"
    assert "nothing to do" in capsys.readouterr().err and _files(run) == before


# 4. A failed evaluation claims nothing; cells impossible for their n or N fail before any other cell runs.
@pytest.mark.parametrize(
    "bad, needle",
    [
        ("seed=-1", "seed=-1"),
        ("threads=0", "threads=0"),
        ("batch_mb=0", "batch_mb=0"),
        ("grid.world_sizes=[20,5] grid.n_targets=[4,2] grid.n_distributions=[8,2] grid.max_agents=[2,32]", "n=5, N=32"),
        ("scenario=walls scenario.obstacles.density=[1]", "scenario.obstacles.density=[1] is not allowed"),
        ("scenario=off_prior scenario.targets.severity=abc", "scenario.targets.severity='abc' is not allowed"),
    ],
)
def test_a_failed_evaluation_claims_no_folder(tmp_path, capsys, bad, needle):
    out = tmp_path / "eval"
    _refused(capsys, lambda: _evaluate(out, *bad.split()), needle)
    assert not out.exists() or not any(p.name != ".locks" for p in out.iterdir())
    assert len(load(_evaluate(out))) == 4  # the corrected run takes the folder


# 5. Settings that cannot apply are refused, naming them; none is dropped without a word.
@pytest.mark.parametrize("ignored", ["env.world.k=500", "controller=greedy", "controller.w_p=0.3", "+model=a"])
def test_a_checkpoint_refuses_world_model_and_controller_settings(tmp_path, capsys, ignored):
    checkpoint = f"checkpoint={REFERENCE_B / 'model.zip'}"
    _refused(capsys, lambda: _evaluate(tmp_path, checkpoint, ignored), ignored, "cannot apply")
    assert not (tmp_path / "evaluation.yaml").exists()


def test_render_refuses_heuristic_options_with_a_checkpoint(tmp_path, capsys):
    from searchrl.render import main

    call = lambda: main(["--checkpoint", str(REFERENCE_B / "model.zip"), "--controller", "greedy",  # noqa: E731
                         "--out", str(tmp_path / "x.gif")])  # fmt: skip
    with pytest.raises(SystemExit):
        call()
    assert "--controller cannot apply with --checkpoint" in capsys.readouterr().err


@pytest.mark.skipif(torch.cuda.is_available(), reason="needs a machine without CUDA")
def test_device_cuda_without_cuda_is_refused_not_run_on_cpu(tmp_path, capsys):
    _refused(capsys, lambda: train(_compose("train", [*TINY, "device=cuda"]), tmp_path, []), "device='cuda'", "cpu")
    assert not (tmp_path / "config.yaml").exists()


# 6. One line, not a traceback, before any work or file.
@pytest.mark.parametrize(
    "override, needle",
    [
        ("seed=-1", "seed=-1"),
        ("algo.learning_rate=-0.1", "algo.learning_rate=-0.1"),
        ("algo.gamma=1.5", "algo.gamma=1.5"),
        ("algo.ent_coef=nan", "algo.ent_coef=nan"),
        ("device=foo", "device='foo'"),
        ("threads=0", "threads=0"),
        ("validation.seed=-3", "validation.seed=-3"),
    ],
)
def test_bad_training_values_get_one_line_before_any_file(tmp_path, capsys, override, needle):
    _refused(capsys, lambda: train(_compose("train", [*TINY, override]), tmp_path, [override]), needle)
    assert not tmp_path.exists() or not any(tmp_path.iterdir())


def test_unreadable_run_files_get_one_line(tmp_path, tiny_run, capsys):
    from searchrl.bench.__main__ import main as bench
    from searchrl.render import main as render

    run = _copy(tiny_run, tmp_path / "run")
    (run / "config.yaml").write_bytes(b"\x00\xff: [unclosed")
    overrides = [f"resume={run}"]
    _refused(capsys, lambda: train(_compose("train", overrides), run / "r", overrides), "config.yaml")
    shutil.copy(REFERENCE_B / "config.yaml", run / "config.yaml")
    corrupt = run / "model.zip"
    corrupt.write_bytes((REFERENCE_B / "model.zip").read_bytes()[:5000])
    gif = tmp_path / "x.gif"
    _refused(capsys, lambda: render(["--checkpoint", str(corrupt), "--out", str(gif)]), "cannot be read")
    _refused(capsys, lambda: bench(["policy", "--checkpoint", str(corrupt)]), "cannot be read")
    _refused(capsys, lambda: _evaluate(tmp_path / "eval", f"checkpoint={corrupt}"), "cannot be read")
    for fps in ("nan", "inf", "0", "1000"):
        _refused(capsys, lambda fps=fps: render(["--fps", fps, "--out", str(gif)]), f"--fps={float(fps)!r}")
    _refused(capsys, lambda: render(["--seed", "-1", "--out", str(gif)]), "--seed=-1")
    assert not gif.exists() and not (tmp_path / "eval" / "evaluation.yaml").exists()


# 7. The PettingZoo env checks types and names: tests/test_marl_envs.py.


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"communication": "yes"}, "communication='yes' is not allowed: True or False"),
        ({"diagonal": 1}, "diagonal=1 is not allowed: True or False"),
        ({"max_steps": 2.5}, "max_steps=2.5 is not allowed: an integer"),
        ({"target_reward": math.nan}, "target_reward=nan is not allowed: a finite number"),
        ({"collision_reward": math.inf}, "collision_reward=inf is not allowed: a finite number"),
        ({"world_size": (20, 30.5)}, r"world_size=\(20, 30.5\) is not allowed: a pair of integers"),
    ],
)
def test_world_config_checks_types(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        SearchParallelEnv(WorldConfig(**kwargs))


# Found by a second round of probing (issue 25's note lists them).
@pytest.mark.parametrize(
    "overrides, needle",
    [
        (["imitation.epochs=7"], "note: imitation.epochs has no effect here"),
        (["algo=a2c", "network.lstm_hidden_size=64"], "note: network.lstm_hidden_size has no effect here"),
        (["imitation.teacher=greedy", "imitation.episodes=1", "imitation.epochs=1", "imitation.batch_sequences=99"],
         "note: imitation.batch_sequences=99 is more than the 8 teacher sequences"),
    ],
)  # fmt: skip
def test_training_settings_without_effect_are_said(tmp_path, capsys, overrides, needle):
    """Said, not refused: one sweep command line may set them for jobs that use them and jobs that do not."""
    overrides = [*overrides, "total_timesteps=0" if "imitation.teacher=greedy" in overrides else "total_timesteps=256"]
    tiny = [o for o in TINY if "algo=a2c" not in overrides or "batch_size" not in o]  # A2C has no minibatches
    train(_compose("train", [*tiny, *overrides]), tmp_path, overrides)
    assert needle in capsys.readouterr().err


def test_seeds_beyond_numpy_are_refused(tmp_path, capsys):
    _refused(capsys, lambda: train(_compose("train", [*TINY, "seed=4294967296"]), tmp_path, []), "seed=4294967296")
    assert not any(tmp_path.iterdir())


def test_budgets_round_to_whole_rollouts_and_are_recorded_so(tmp_path, capsys):
    from omegaconf import OmegaConf

    overrides = ["total_timesteps=300", "checkpoint_every=100"]  # rollouts of 256 agent-steps
    final = train(_compose("train", [*TINY, *overrides]), tmp_path, overrides)
    assert "total_timesteps=300 rounds up to 512" in capsys.readouterr().err
    record = OmegaConf.load(tmp_path / "config.yaml")
    assert (record.total_timesteps, record.checkpoint_every) == (512, 256)
    assert RecurrentPPO.load(final).num_timesteps == 512


def test_a_run_killed_before_its_first_checkpoint_resumes_from_step_0(tmp_path, tiny_run, capsys):
    run = _copy(tiny_run, tmp_path / "run")
    shutil.rmtree(run / "checkpoints")
    before = (run / "progress.csv").read_text()
    overrides = [f"resume={run}", "total_timesteps=512"]
    final = train(_compose("train", overrides), run / "r", overrides)
    assert "no checkpoint yet" in capsys.readouterr().err and RecurrentPPO.load(final).num_timesteps == 512
    # The restart logs every step once: the killed attempt's rows and events are moved aside, not mixed in.
    steps = pd.read_csv(run / "progress.csv")["time/total_timesteps"].tolist()
    assert steps == [256, 512, 512]  # two rollouts, then the final validation's row
    assert (run / "killed" / "0" / "progress.csv").read_text() == before
    assert (run / "killed" / "0" / "tensorboard").is_dir()


@pytest.mark.parametrize(
    "overrides, needle",
    [
        (["env.world.n_agents=3"], "env.world.n_agents cannot apply"),
        (["deterministic=true"], "deterministic cannot apply"),
        (["env.n_worlds=7"], "env.n_worlds cannot apply"),
        (["controller=random", "+controller.horizon=3"], "controller.horizon=3 is not allowed"),
        (["controller.w_p=nan"], "controller.w_p=nan"),
        (["controller=greedy", "controller.w_p=inf"], "controller.w_p=inf"),
        (["seed=99999999999999999999"], "seed=99999999999999999999"),
        (["out_dir= "], "out_dir='' is not allowed: a folder (leave it out"),
        (["checkpoint="], "checkpoint='' does not exist (expected a model.zip of a run)"),
        (["grid.world_sizes=[]", "grid.n_targets=[]", "grid.n_distributions=[]", "grid.max_agents=[]"], "one or more"),
        (["grid.world_sizes=[20,20]", "grid.n_targets=[4,2]", "grid.n_distributions=[8,8]", "grid.max_agents=[2,2]"],
         "each size once"),
    ],
)  # fmt: skip
def test_evaluation_settings_that_cannot_apply_are_refused(tmp_path, capsys, overrides, needle):
    _refused(capsys, lambda: _evaluate(tmp_path / "eval", *overrides), needle)
    assert not (tmp_path / "eval").exists()


@pytest.mark.parametrize(
    "argv, needles",
    [
        (["controller=greedy", "+model=surfing"], ["+model=surfing", "heuristic controller", "controller=surfing"]),
        (["+experiment=term/bb"], ["+experiment=term/bb", "did you mean experiment=term/b?"]),
        (["scenario=wals", "seed=3"], ["scenario=wals", "did you mean scenario=walls?", "files of conf/scenario/"]),
        (["-m", "controller=surfing,coverag"], ["controller=surfing,coverag", "'coverag'", "controller=coverage?"]),
        (["suite=prior_eror"], ["conf/suite/ has no 'prior_eror'", "suite=prior_error?"]),
    ],
)  # fmt: skip
def test_a_group_option_that_does_not_exist_is_one_line_before_hydra(capsys, argv, needles):
    _refused(capsys, lambda: check_group_choices(argv), *needles)


def test_group_options_that_exist_and_what_hydra_checks_pass_the_command_line_check():
    check_group_choices(["+experiment=term/b", "scenario=walls", "-m", "controller=surfing,coverage", "+model=b",
                         "suite=null", "hydra/launcher=joblib", "controller=choice(surfing,nope)", "~scenario",
                         "env.world.fov=5", "machine=gpu", "algo=a2c"])  # fmt: skip


@pytest.mark.parametrize(
    "argv, app, needles",
    [
        (["grid.repeats=1.5"], "evaluate", ["grid.repeats=1.5 is not allowed", "could not be converted to Int"]),
        (["-m", "controller=surfing", "grid.repeats=1,1.5"], "evaluate",
         ["grid.repeats=1.5 (of grid.repeats=1,1.5) is not allowed"]),
        (["controller=surfing", "controller.w_p=abc"], "evaluate", ["controller.w_p=abc is not allowed", "to Float"]),
        (["-m", "controller=surfing,coverage", "controller.radius=x"], "evaluate", ["controller.radius=x"]),
        (["seed=abc"], "train", ["seed=abc is not allowed", "'abc' of type 'str'"]),
        (["+model=b", "env.world.fov=x"], "train", ["env.world.fov=x is not allowed"]),
        (["+experiment=term/b", "total_timesteps=1e6"], "train", ["total_timesteps=1e6 is not allowed"]),
        (["network.lstm_hiden=64"], "train",
         ["network.lstm_hiden=64 is not allowed: no such setting (did you mean network.lstm_hidden_size?)"]),
        (["controller=surfing", "controller.w_pp=1"], "evaluate",
         ["controller.w_pp=1 is not allowed: no such setting (did you mean controller.w_p?)"]),
        (["-m", "grid.map_per_cell=2,3"], "evaluate",
         ["grid.map_per_cell=2,3 is not allowed: no such setting (did you mean grid.maps_per_cell?)"]),
        (["network.zzz=1"], "train", ["network.zzz=1 is not allowed: no such setting"]),
        (["-m", "+model=b", "hydra/sweeper=optuna_searchrl", "hydra.sweeper.storage=sqlite:////nowhere/study.db"],
         "train", ["hydra.sweeper.storage='sqlite:////nowhere/study.db' is not allowed: its folder '/nowhere' does "
                   "not exist"]),
    ],
)  # fmt: skip
def test_a_job_that_cannot_compose_is_one_line_before_hydra(capsys, argv, app, needles):
    _refused(capsys, lambda: check_jobs_compose(argv, app), *needles)


def test_jobs_that_compose_and_what_only_the_sweeper_draws_pass_the_compose_check():
    check_jobs_compose(["grid.world_sizes=[20,40]", "controller=surfing", "controller.w_p=0.5", "seed=3", "-m",
                        "device=cuda", "scenario.obstacles.density=0.3", "+foo=1", "threads=1,2", "hydra.run.dir=x",
                        "grid.repeats=choice(1,2)", "checkpoint=null", "out_dir=${hydra:runtime.cwd}/e",
                        "grid.maps_per_cell=range(1,3)", "hydra/launcher=joblib"], "evaluate")  # fmt: skip
    check_jobs_compose(
        [
            "algo.n_epochs=2",
            "+model=b",
            "algo.learning_rate=tag(log,interval(1e-5,1e-3))",
            "env.world.fov=11",
            "machine=gpu",
            "total_timesteps=4096",
            "-m",
            "seed=0,1",
        ],
        "train",
    )
    check_jobs_compose(["+experiment=term/b", "--cfg", "job", "seed=abc"], "train")  # other flags: Hydra's to check


@pytest.mark.parametrize(
    "args, needle",
    [
        (["scenario=wals"], "did you mean scenario=walls?"),
        (["-m", "controller=surfing", "grid.repeats=1.5,1"], "grid.repeats=1.5 (of grid.repeats=1.5,1) is not allowed"),
    ],
)  # fmt: skip
def test_the_apps_name_a_missing_group_option_or_a_mistyped_value_before_hydra(tmp_path, args, needle):
    """Hydra's refusal of either is a page or five lines, and in a multirun it ends the sweep at that job: here the
    command is refused in one line and nothing is written."""
    cmd = [sys.executable, "-m", "searchrl.evaluate", *args, f"out_dir={tmp_path}/e", f"hydra.run.dir={tmp_path}/h",
           f"hydra.sweep.dir={tmp_path}/s"]  # fmt: skip
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and needle in out.stderr, out.stderr
    assert not any(tmp_path.iterdir())


def test_evaluation_output_folders_are_checked_first(tmp_path, capsys):
    (tmp_path / "afile").write_text("")
    _refused(capsys, lambda: _evaluate(tmp_path / "afile" / "sub"), "is a file, not a folder")
    (tmp_path / "eval").mkdir()
    (tmp_path / "eval" / "cells").write_text("")
    _refused(capsys, lambda: _evaluate(tmp_path / "eval"), "out_dir/cells=", "a folder")
    (tmp_path / "eval2").mkdir()
    (tmp_path / "eval2" / "evaluation.yaml").write_text("")
    _refused(capsys, lambda: _evaluate(tmp_path / "eval2"), "evaluation.yaml cannot be read")
    assert len(load(_evaluate(tmp_path / "cov", "controller=coverage", "controller.radius=9"))) == 4  # thin blocks


def test_cli_flags_and_world_bounds_are_checked_before_work(tmp_path, capsys):
    from searchrl.bench.__main__ import main as bench
    from searchrl.command_line import check_resume_argument
    from searchrl.render import main as render

    gif = tmp_path / "x.gif"
    (tmp_path / "afile").write_text("")
    _refused(capsys, lambda: render(["--fps", "0.001", "--out", str(gif)]), "--fps=0.001")
    _refused(capsys, lambda: render(["--agents", "0", "--out", str(gif)]), "--agents=0")
    _refused(capsys, lambda: render(["--out", str(tmp_path / "afile" / "x.gif")]), "is a file, not a folder")
    _refused(capsys, lambda: render(["--n", "100000", "--out", str(gif)]), "world_size=(100000, 100000)")
    _refused(capsys, lambda: bench(["memory", "--maps", "3"]), "unrecognized arguments: --maps 3")
    _refused(capsys, lambda: bench(["train", "--updates", "1000000000"]), "--updates=1000000000")
    checkpoint = str(REFERENCE_B / "model.zip")
    _refused(capsys, lambda: bench(["eval", "--checkpoint", checkpoint, "--controller", "greedy"]), "cannot apply")
    _refused(capsys, lambda: check_resume_argument([f"resume={tmp_path / 'afile'}"]), "a run folder")
    assert not gif.exists()
    for kwargs, needle in (({"fov": 103}, "fov=103"), ({"prob_variance_scale": 1e308}, "prob_variance_scale")):
        with pytest.raises(ConfigError, match=needle):
            WorldConfig(**kwargs)


def test_a_module_that_exits_an_out_file_and_a_world_that_is_a_number_are_refused_in_one_line(tmp_path, capsys):
    (tmp_path / "exits.py").write_text("import sys\nsys.exit(3)\n")
    sys.path.insert(0, str(tmp_path))
    try:
        from searchrl.command_line import import_from_command_line

        _refused(capsys, lambda: import_from_command_line(["extensions=[exits]"]), "'exits'", "sys.exit(3)")
    finally:
        sys.path.remove(str(tmp_path))
    _refused(capsys, lambda: _evaluate(tmp_path / "eval", "controller=surfing", "env.world=5"), "env.world=5")
    _refused(capsys, lambda: train(_compose("train", ["+model=b", "env.world=5"]), tmp_path / "run"), "env.world=5")
    (tmp_path / "table.md").write_text("")
    out = _evaluate(tmp_path / "surfing", "controller=surfing")
    result = run_script("table3.py", str(out), "--out", str(tmp_path / "table.md"))
    assert result.returncode == 1 and result.stderr.strip().splitlines()[-1].endswith(
        "is a file, not a folder; give a folder for the tables"
    )


def test_env_apis_refuse_wrong_arguments_with_value_errors():
    from searchrl.envs.single_env import SearchEnv
    from searchrl.envs.vec_env import SearchVecEnv

    config = WorldConfig(world_size=(10, 10), n_targets=(2, 2), n_agents=2, max_steps=5)
    single = SearchEnv(config)
    with pytest.raises(ValueError, match="seed=-1"):
        single.reset(seed=-1)
    for make in (lambda: SearchEnv({"world_size": (10, 10)}), lambda: SearchVecEnv({"n_agents": 2}, 1, 0)):
        with pytest.raises(ValueError, match=r"config=.* is not allowed"):
            make()
    env = SearchParallelEnv(config)
    with pytest.raises(RuntimeError, match="before reset"):
        env.step({})
    env.reset(seed=0)
    for call, needle in ((lambda: env.step([0, 0]), "a dict"), (lambda: env.observation_space("agent_9"), "agent_9")):
        with pytest.raises(ValueError, match=needle):
            call()
    for env in (SearchParallelEnv(config, render_mode="rgb_array"), SearchEnv(config, render_mode="rgb_array")):
        with pytest.raises(RuntimeError, match=r"render\(\) called before reset\(\)"):
            env.render()
    vec = SearchVecEnv(config, 2, seed=0, render_mode="rgb_array")
    with pytest.raises(ResetNeeded, match=r"before calling env\.reset"):
        vec.get_images()
    with pytest.raises(ValueError, match="seed='3' is not allowed"):
        vec.seed("3")
    vec.reset()
    for actions, needle in ((np.full(4, 1.7), "dtype float64"), (np.zeros(3, np.int64), r"one action per slot")):
        with pytest.raises(ValueError, match=needle):
            vec.step(actions)


# Resume bookkeeping: a damaged log refused before anything is rewritten, the clock continued, a path with spaces.
@pytest.mark.parametrize("damage", ["garbage", "truncated"])
def test_a_damaged_log_is_refused_before_anything_is_rewritten(tmp_path, tiny_run, capsys, damage):
    run = _copy(tiny_run, tmp_path / "run")
    log = run / "progress.csv"
    if damage == "garbage":
        log.write_bytes(b"\xff\xfe\x00garbage\x81\n")
        needle = "progress.csv (the run's log) is not UTF-8 text"
    else:  # half the file: the rows stop at a step far before the checkpoint
        lines = log.read_text().splitlines(keepends=True)
        log.write_text("".join(lines[: len(lines) // 2]))
        needle = "jumps from step"
    record, text = (run / "config.yaml").read_bytes(), log.read_bytes()
    overrides = [f"resume={run}", "total_timesteps=2304"]
    _refused(capsys, lambda: train(_compose("train", overrides), run / "resumed", overrides), needle)
    assert (run / "config.yaml").read_bytes() == record and log.read_bytes() == text


def test_a_deleted_log_is_refused_and_a_cut_final_row_is_validated_again(tmp_path, tiny_run, capsys):
    run = _copy(tiny_run, tmp_path / "run")
    (run / "progress.csv").unlink()
    overrides = [f"resume={run}", "total_timesteps=2048"]
    _refused(capsys, lambda: train(_compose("train", overrides), run / "resumed", overrides), "progress.csv is missing")
    assert not (run / "progress.csv").exists()
    run = _copy(tiny_run, tmp_path / "cut")
    text = (run / "progress.csv").read_text()
    (run / "progress.csv").write_text(text[: text.rstrip("\n").rfind("\n") + 40])  # the final row cut by a kill
    train(_compose("train", overrides := [f"resume={run}", "total_timesteps=2048"]), run / "resumed", overrides)
    assert "the final validation at step 2048 is missing from its log: run again" in capsys.readouterr().err
    assert (run / "score.json").read_text() == (tiny_run / "score.json").read_text()  # the same worlds and weights


def test_a_resumed_log_continues_the_runs_clock(tmp_path, tiny_run):
    """time/time_elapsed and time/iterations go on from the checkpoint's row instead of starting again."""
    run = _copy(tiny_run, tmp_path / "run")
    overrides = [f"resume={run}", "total_timesteps=2560"]
    train(_compose("train", overrides), run / "resumed", overrides)
    rows = pd.read_csv(run / "progress.csv")
    rollouts = rows[rows["time/iterations"].notna()]
    assert rollouts["time/iterations"].tolist() == list(range(1, len(rollouts) + 1))
    assert rollouts["time/time_elapsed"].is_monotonic_increasing


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else b"<dir>" for p in sorted(folder.rglob("*"))}


def test_a_refused_training_writes_nothing_in_the_folder_it_names(tmp_path):
    """Hydra's record of a run (.hydra/) is written once the run's checks pass: a new run into a finished run's
    folder, or a resume of a folder that is no run, is refused before Hydra touches either folder."""
    run, app = tmp_path / "run", [sys.executable, "-m", "searchrl.train"]
    made = subprocess.run([*app, *TINY, f"hydra.run.dir={run}"], capture_output=True, text=True, cwd=ROOT)
    assert made.returncode == 0, made.stderr[-2000:]
    assert "- network=small" in (run / ".hydra" / "overrides.yaml").read_text()
    assert "seed: 0" in (run / ".hydra" / "config.yaml").read_text()
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    before = {run: _snapshot(run), other: _snapshot(other)}
    for args, folder, needle in (
        ([*TINY, "seed=5", f"hydra.run.dir={run}"], run, f"{run} already holds a run: continue it with resume="),
        ([f"resume={other}"], other, f"resume='{other}' is not a run directory: it has no config.yaml"),
    ):
        refused = subprocess.run([*app, *args], capture_output=True, text=True, cwd=ROOT)
        lines = refused.stderr.strip().splitlines()
        assert refused.returncode == 2 and lines[-1].startswith(f"error: {needle}"), refused.stderr
        assert "Traceback" not in refused.stderr and _snapshot(folder) == before[folder]


def test_a_folder_whose_parts_link_out_of_it_is_refused_and_nothing_there_is_touched(tmp_path, tiny_run, capsys):
    run = _copy(tiny_run, tmp_path / "run")
    elsewhere = tmp_path / "elsewhere"
    (run / "checkpoints").rename(elsewhere)
    (run / "checkpoints").symlink_to(elsewhere)
    kept = _snapshot(elsewhere)
    overrides = [f"resume={run}", "total_timesteps=4096"]
    resume = lambda: train(_compose("train", overrides), run / "resumed", overrides)  # noqa: E731
    _refused(capsys, resume, "checkpoints is a link out")
    assert _snapshot(elsewhere) == kept
    out = _evaluate(tmp_path / "eval")
    (out / "cells").rename(tmp_path / "cells")
    (out / "cells").symlink_to(tmp_path / "cells")
    _refused(capsys, lambda: _evaluate(out, "controller=coverage"), "out_dir=", "cells is a link out")
    assert len(list((tmp_path / "cells").iterdir())) == 2  # its two cells, no third


def test_a_model_zip_with_an_entry_twice_is_refused(tmp_path):
    import zipfile

    twice = tmp_path / "model.zip"
    shutil.copyfile(REFERENCE_B / "model.zip", twice)
    with zipfile.ZipFile(twice, "a") as archive, pytest.warns(UserWarning, match="Duplicate name"):
        archive.writestr("data", "{}")
    with pytest.raises(ValueError, match="holds the entry 'data' twice"):
        load_checkpoint(twice, policy_record(run_config(REFERENCE_B / "model.zip"), twice))


def test_a_run_folder_with_a_space_in_its_path_resumes(tmp_path, tiny_run, capsys):
    from searchrl.command_line import check_resume_argument

    run = _copy(tiny_run, tmp_path / "my run")
    check_resume_argument([f"resume='{run}'"])  # quoted for Hydra, as a shell passes it
    check_resume_argument([f'resume="{run}"'])
    with pytest.raises(SystemExit), exits():
        check_resume_argument([f"resume='{tmp_path / 'no run'}'"])
    assert "is not allowed: a run folder" in capsys.readouterr().err
    with mock.patch("searchrl.command_line.os.access", return_value=False):  # a read-only folder (root writes any)
        _refused(capsys, lambda: check_resume_argument([f"resume={run}"]), "the run folder cannot be written")


@pytest.mark.parametrize("app", ["train", "evaluate"])
def test_a_full_disk_is_said_in_one_line(tmp_path, capsys, monkeypatch, app):
    """ENOSPC while writing a checkpoint or a cell: one line naming the file and what to do, no traceback."""
    import errno

    import searchrl.atomic

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device", "disk")

    monkeypatch.setattr(searchrl.atomic.os, "fsync", full)
    if app == "train":
        overrides = ["total_timesteps=256"]
        call = lambda: train(_compose("train", [*TINY, *overrides]), tmp_path / "run", overrides)  # noqa: E731
        needle = "the run resumes from its last checkpoint"
    else:
        call = lambda: _evaluate(tmp_path / "eval", "controller=random")  # noqa: E731
        needle = "run the same command again"  # the record is the first file the evaluation writes
    _refused(capsys, call, "No space left on device writing disk", needle)


def test_an_out_dir_that_cannot_hold_folders_is_refused_before_work(tmp_path, capsys):
    _refused(capsys, lambda: _evaluate(Path("/proc/searchrl_eval"), "controller=random"),
             "out_dir='/proc/searchrl_eval' is not allowed: its folders cannot be made there")  # fmt: skip


def test_a_world_larger_than_memory_is_refused_in_one_line():
    import searchrl

    with pytest.raises(ValueError, match=r"n_agents=4096, world_size=\(2048, 2048\) is not allowed here: .* GiB"):
        searchrl.parallel_env(n_agents=4096, world_size=2048)
