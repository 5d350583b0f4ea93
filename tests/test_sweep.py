"""Sweeps: every run's score, the Optuna sweeper end to end (tiny budget, resumed study), the sweep table."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from PIL import Image

from searchrl.multirun import exits
from searchrl.reporting.sweep import load_jobs, mean_ci, score_table, setting_keys, validation_curves
from searchrl.train.run_record import run_score, write_score
from tests.scripts import run_script

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
TINY = ["+model=b", "total_timesteps=512", "env.n_worlds=2", "env.world.n_agents=4", "env.world.world_size=[12,20]",
        "env.world.n_targets=[2,4]", "env.world.n_distributions=[4,8]", "network=small", "algo.batch_size=128",
        "checkpoint_every=1024", "validation.every=256", "validation.n_worlds=2", "progress_bar=false",
        "threads=1"]  # fmt: skip


def _optuna(sweep_dir: Path, storage: Path, trials: int) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "searchrl.train", "-m", "hydra/sweeper=optuna_searchrl", *TINY,
           f"hydra.sweeper.n_trials={trials}", f"hydra.sweeper.storage=sqlite:///{storage}",
           f"hydra.sweep.dir={sweep_dir}"]  # fmt: skip
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def optuna_sweep(tmp_path_factory):
    base = tmp_path_factory.mktemp("optuna")
    _optuna(base / "sweep", base / "study.db", trials=2)
    return base


def test_optuna_sweeps_the_search_space_and_reports_the_best_trial(optuna_sweep):
    sweep = optuna_sweep / "sweep"
    jobs = load_jobs(sweep)
    assert len(jobs) == 2 and jobs.finished.all() and (jobs.validations == 2).all()  # at 1024 and the final 2048
    # Each trial draws every parameter of conf/hydra/sweeper/optuna_searchrl.yaml, inside its range.
    assert jobs["algo.learning_rate"].between(3e-5, 3e-3).all() and jobs["algo.ent_coef"].between(0, 0.05).all()
    assert set(jobs["algo.gamma"]) <= {0.95, 0.98, 0.99, 0.995}
    best = yaml.safe_load((sweep / "optimization_results.yaml").read_text())
    assert best["best_value"] == pytest.approx(jobs.score.max())  # maximised: the score is a found fraction
    winner = jobs.loc[jobs.score.idxmax()]
    assert best["best_params"]["algo.learning_rate"] == pytest.approx(winner["algo.learning_rate"])


@pytest.mark.slow  # the study's first sweep is in the default run
def test_the_same_command_into_the_same_folder_resumes_the_study(optuna_sweep):
    """The new trial's job is numbered 0 again, with other parameters: its folder, named by them, goes beside the
    first trials' folders, which stay untouched."""
    import optuna

    sweep = optuna_sweep / "sweep"
    first = load_jobs(sweep)
    before = {p.parent.name: p.stat().st_mtime_ns for p in sweep.glob("*/model.zip")}
    _optuna(sweep, optuna_sweep / "study.db", trials=1)
    study = optuna.load_study(study_name="b_recurrent_ppo", storage=f"sqlite:///{optuna_sweep / 'study.db'}")
    assert len(study.trials) == 3 and all(t.state.name == "COMPLETE" for t in study.trials)
    assert study.trials[2].params["algo.learning_rate"] not in set(first["algo.learning_rate"])  # a new trial
    after = {p.parent.name: p.stat().st_mtime_ns for p in sweep.glob("*/model.zip")}
    (new,) = set(after) - set(before)
    assert new.startswith("0_") and f"algo.learning_rate={study.trials[2].params['algo.learning_rate']}" in new
    assert {name: after[name] for name in before} == before  # untouched


@pytest.mark.slow
def test_a_resumed_study_proposes_what_an_uninterrupted_one_does(optuna_sweep):
    """Each trial's draws are seeded by its number: two trials, then one more in the same study, propose what one
    sweep of three trials proposes."""
    import optuna

    storage = f"sqlite:///{optuna_sweep / 'study.db'}"
    if len(optuna.load_study(study_name="b_recurrent_ppo", storage=storage).trials) == 2:  # not resumed above yet
        _optuna(optuna_sweep / "sweep", optuna_sweep / "study.db", trials=1)
    study = optuna.load_study(study_name="b_recurrent_ppo", storage=storage)
    _optuna(optuna_sweep / "whole", optuna_sweep / "whole.db", trials=3)
    whole = optuna.load_study(study_name="b_recurrent_ppo", storage=f"sqlite:///{optuna_sweep / 'whole.db'}")
    assert [t.params for t in whole.trials] == [t.params for t in study.trials]


def _progress(path: Path, rows: list[tuple[int, float | None]]) -> None:
    frame = pd.DataFrame(rows, columns=["time/total_timesteps", "val/found_fraction"])
    frame.to_csv(path / "progress.csv", index=False)


def test_the_score_averages_the_last_validations(tmp_path):
    _progress(tmp_path, [(256, None), (512, 0.2), (768, None), (1024, 0.4), (1280, 0.6), (1280, 0.8)])
    record = run_score(tmp_path, last=3)
    assert record["score"] == pytest.approx(0.6) and record["validations"] == 3
    assert record["steps"] == [1024, 1280, 1280]
    assert run_score(tmp_path, last=10)["validations"] == 4
    _progress(tmp_path, [(256, None)])
    assert math.isnan(run_score(tmp_path, last=3)["score"])


def test_a_run_without_periodic_validation_is_scored_on_its_final_model(tmp_path):
    from searchrl.train.app import train
    from tests.test_train import _compose

    overrides = [*TINY, "validation.every=0"]
    train(_compose(overrides), tmp_path, overrides)
    record = json.loads((tmp_path / "score.json").read_text())
    assert record["validations"] == 1 and record["steps"] == [512] and 0 <= record["score"] <= 1
    with pytest.raises(SystemExit), exits():
        train(_compose([*TINY, "validation.score_last=0"]), tmp_path / "bad", [])
    assert not (tmp_path / "bad").exists()


def make_fixture_sweep(base: Path) -> Path:
    """A multirun folder as Hydra and the training app write it: 2 learning rates x 3 seeds, known scores and
    curves, and one job killed before its score."""
    scores = {"0.0003": [0.50, 0.52, 0.54], "0.001": [0.60, 0.70, 0.65]}
    job = 0
    for lr, values in scores.items():
        for seed, score in enumerate(values):
            folder = base / f"{job}_b_seed{seed}"
            (folder / ".hydra").mkdir(parents=True)
            overrides = ["+model=b", f"algo.learning_rate={lr}", f"seed={seed}", "hydra.launcher.n_jobs=2"]
            (folder / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(overrides))
            _progress(folder, [(100, None), (200, score), (300, None), (400, score)])
            write_score(folder, 2)  # as the run writes it: the mean of its last two validations
            job += 1
    killed = base / f"{job}_b_seed3"
    (killed / ".hydra").mkdir(parents=True)
    (killed / ".hydra" / "overrides.yaml").write_text(yaml.safe_dump(["+model=b", "algo.learning_rate=0.001",
                                                                      "seed=3"]))  # fmt: skip
    return base


def test_the_sweep_table_gives_each_setting_its_mean_and_interval_over_seeds(tmp_path):
    sweep = make_fixture_sweep(tmp_path)
    jobs = load_jobs(sweep)
    assert setting_keys(jobs) == ["algo.learning_rate"] and len(jobs) == 7 and jobs.finished.sum() == 6
    table = score_table(jobs)
    assert list(table["algo.learning_rate"]) == [0.001, 0.0003]  # best first
    assert list(table.seeds) == [3, 3]  # the killed job counts as no seed
    assert table.score.to_numpy() == pytest.approx([0.65, 0.52])
    assert (table.low <= table.score).all() and (table.score <= table.high).all()
    assert table.loc[0, "low"] >= 0.60 and table.loc[0, "high"] <= 0.70  # within the seeds' range
    curves = validation_curves(sweep, jobs)
    assert len(curves) == 12 and set(curves.step) == {200, 400}


def test_mean_ci_of_one_and_of_equal_values():
    assert math.isnan(mean_ci(np.array([0.5]))[1])
    assert mean_ci(np.array([0.5, 0.5, 0.5])) == (0.5, 0.5, 0.5)
    assert math.isnan(mean_ci(np.array([math.nan]))[0])


def test_the_sweep_notebook_writes_table_and_plot(tmp_path):
    sweep = make_fixture_sweep(tmp_path / "multirun")
    out = run_script("sweep.py", str(sweep), "--out", str(tmp_path / "out"))
    assert out.returncode == 0, out.stderr[-3000:]
    table = (tmp_path / "out" / "sweep.md").read_text()
    assert "| 0.001 | 3 | 0.650 |" in table and "| 0.0003 | 3 | 0.520 |" in table
    assert pd.read_csv(tmp_path / "out" / "sweep.csv").shape[0] == 2
    with Image.open(tmp_path / "out" / "sweep_curves.png") as image:
        assert (image.format, image.size) == ("PNG", (780, 480))
    missing = run_script("sweep.py", str(tmp_path / "nowhere"))
    assert missing.returncode == 1 and missing.stderr.strip().count("\n") == 0 and "nowhere" in missing.stderr


def test_a_refused_trial_is_marked_failed_not_left_running(tmp_path):
    """A trial whose run is refused (here every trial: algo.n_epochs=0) is a failed job: the study records it FAIL,
    where the refusal's exit used to end the sweep with the trial RUNNING for ever; its line, no traceback, and no
    job folder left behind."""
    import optuna

    cmd = [sys.executable, "-m", "searchrl.train", "-m", "hydra/sweeper=optuna_searchrl", *TINY, "algo.n_epochs=0",
           "hydra.sweeper.n_trials=1", f"hydra.sweeper.storage=sqlite:///{tmp_path / 'study.db'}",
           f"hydra.sweep.dir={tmp_path / 'sweep'}"]  # fmt: skip
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode != 0 and "error: algo.n_epochs=0 is not allowed: must be >= 1" in out.stderr
    assert "Traceback" not in out.stderr and not [p for p in (tmp_path / "sweep").iterdir() if p.name[0].isdigit()]
    study = optuna.load_study(study_name="b_recurrent_ppo", storage=f"sqlite:///{tmp_path / 'study.db'}")
    assert [t.state for t in study.trials] == [optuna.trial.TrialState.FAIL]


def test_the_study_is_stored_in_the_checkout_whatever_the_working_folder(tmp_path):
    """`python -m searchrl.train -m hydra/sweeper=optuna_searchrl ...` started outside the checkout keeps its study
    in the checkout's runs/ (a path relative to the working folder failed there)."""
    cmd = [sys.executable, "-m", "searchrl.train", "hydra/sweeper=optuna_searchrl", "+model=b", "--cfg", "hydra",
           "--package", "hydra.sweeper", "--resolve"]  # fmt: skip
    out = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    storage = yaml.safe_load(out.stdout)["storage"]  # the package's keys, printed at the top level
    assert storage == f"sqlite:///{ROOT / 'runs' / 'optuna.db'}"


def test_a_trial_left_running_by_a_dead_sweep_is_marked_failed_at_the_next(tmp_path):
    """A sweep killed with -9 leaves its trial RUNNING: the next sweep's first proposal marks it FAIL when its sweep
    ran on this host and is gone (or never marked its trials), and leaves live or other hosts' sweeps alone."""
    import os
    import socket

    import optuna

    from searchrl.train.optuna_sampler import OWNER, TrialSeededTPESampler

    study = optuna.create_study(storage=f"sqlite:///{tmp_path / 's.db'}", study_name="s", direction="maximize")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    owners = {"dead": f"{socket.gethostname()}:{int(dead.stdout)}", "alive": f"{socket.gethostname()}:{os.getppid()}",
              "elsewhere": "another-host:1", "unmarked": None}  # fmt: skip
    for owner in owners.values():
        trial = study.ask()
        if owner is not None:
            study._storage.set_trial_system_attr(trial._trial_id, OWNER, owner)
    sampler = TrialSeededTPESampler(seed=0)
    resumed = optuna.load_study(study_name="s", storage=f"sqlite:///{tmp_path / 's.db'}", sampler=sampler)
    resumed.ask({"x": optuna.distributions.UniformDistribution(0, 1)})  # the new sweep's first proposal
    states = [t.state.name for t in resumed.trials]
    assert states == ["FAIL", "RUNNING", "RUNNING", "FAIL", "RUNNING"], states
    assert resumed.trials[-1].system_attrs[OWNER] == f"{socket.gethostname()}:{os.getpid()}"


def _grid(sweep_dir: Path, *more: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "searchrl.train", "-m", *TINY, "seed=0,1", f"hydra.sweep.dir={sweep_dir}", *more]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)


# In the default run (three multiruns of two tiny trainings, about 30 s): docs/training.md promises it.
def test_a_grid_sweep_started_again_in_its_folder_continues_it(tmp_path):
    """Job 0 finished is not trained again, job 1 killed after a checkpoint resumes from it; a sweep of other
    overrides into the same folder trains each job beside the old one (named by its overrides); a job whose folder
    holds a run of the same overrides but other settings (a default changed since) fails with one line naming the
    setting, and trains nothing."""
    sweep = tmp_path / "sweep"
    assert _grid(sweep).returncode == 0
    first, second = sorted(p for p in sweep.iterdir() if p.name[0].isdigit())
    trained = (first / "model.zip").stat().st_mtime_ns
    for name in ("model.zip", "score.json"):  # job 1 as a kill after its last checkpoint leaves it
        (second / name).unlink()
    again = _grid(sweep)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "holds this job's finished run: not trained again" in again.stderr
    assert f"resuming {second} from step_" in again.stderr
    assert (first / "model.zip").stat().st_mtime_ns == trained and (second / "score.json").is_file()
    beside = _grid(sweep, "algo.learning_rate=0.001")
    assert beside.returncode == 0, beside.stderr[-3000:]
    jobs = sorted(p for p in sweep.iterdir() if p.name[0].isdigit())
    beside_jobs = [job for job in jobs if job not in (first, second)]  # named by their other overrides
    assert len(jobs) == 4 and all("algo.learning_rate=0.001" in (j / ".hydra" / "overrides.yaml").read_text()
                                  for j in beside_jobs)  # fmt: skip
    assert (first / "model.zip").stat().st_mtime_ns == trained
    saved = first / "config.yaml"  # as if the default learning rate had changed since job 0 ran
    assert "learning_rate: 0.0003" in saved.read_text()
    saved.write_text(saved.read_text().replace("learning_rate: 0.0003", "learning_rate: 0.0005"))
    other = _grid(sweep)
    assert other.returncode == 1, other.stderr[-3000:]
    assert f"{first} holds a run of other settings (algo.learning_rate: 0.0005 there, 0.0003 now)" in other.stderr
    assert f"{second} holds a run of other" not in other.stderr  # job 1's run is of these settings: not trained again
    assert (first / "model.zip").stat().st_mtime_ns == trained


SWEEP_DAMAGES = {
    "deleted": lambda path, other: path.unlink(),
    "truncated": lambda path, other: path.write_bytes(path.read_bytes()[: path.stat().st_size // 2]),
    "garbage": lambda path, other: path.write_bytes(b"\x00\xffnot this file" * 9),
    "swapped": lambda path, other: shutil.copy(other, path),  # job 1's file of that name
}


@pytest.mark.slow  # a sweep of two tiny trainings, 23 notebook runs and 4 sweep reruns: about three minutes
def test_a_sweep_folder_repairs_or_refuses_each_damaged_file_and_mixes_nothing(tmp_path):
    """Each sweep-level file of a finished two-job sweep (its multirun.yaml, job 0's overrides, score, log and
    configs) in turn deleted, truncated, overwritten or swapped for job 1's: the sweep table either equals the
    undamaged one or is refused in one line naming the file (a lost score counts the job as unfinished, and the
    sweep's rerun writes it again from the job's log); nothing of the folder is changed by the table."""
    clean = tmp_path / "clean"
    assert _grid(clean).returncode == 0
    want = run_script("sweep.py", str(clean), "--out", str(tmp_path / "want"))
    assert want.returncode == 0, want.stderr[-2000:]
    wanted = (tmp_path / "want" / "sweep.csv").read_text()
    job, other = sorted(p.name for p in clean.iterdir() if p.name[0].isdigit())
    files = ["multirun.yaml", *(f"{job}/{name}" for name in (".hydra/overrides.yaml", "score.json", "progress.csv",
                                                                "config.yaml", ".hydra/config.yaml"))]  # fmt: skip
    outcomes = {}
    for rel in files:
        for name, damage in SWEEP_DAMAGES.items():
            if rel == "multirun.yaml" and name == "swapped":
                continue  # one per sweep
            # named without the job's `=` and `,`: the folder is a Hydra override's value in the rerun below
            folder = tmp_path / "damaged" / f"{rel.replace(job, 'job0').replace('/', '_')}_{name}"
            shutil.copytree(clean, folder)
            damage(folder / rel, clean / rel.replace(job, other))
            before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
            out = run_script("sweep.py", str(folder), "--out", str(tmp_path / "out" / folder.name))
            assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before
            table = tmp_path / "out" / folder.name / "sweep.csv"
            if out.returncode == 0:
                outcome = "same" if table.read_text() == wanted else "unfinished"
                assert outcome == "same" or pd.read_csv(table).seeds.tolist() == [1]
            else:
                lines = out.stderr.strip().splitlines()
                assert out.returncode == 1 and len(lines) == 1 and "Traceback" not in out.stderr, out.stderr[-2000:]
                assert str(folder / rel.split("/")[0]) in lines[0] or rel == "multirun.yaml"
                outcome = "refused"
            if rel.endswith("score.json"):  # the sweep again: its score from its own log
                again = _grid(folder)
                assert again.returncode == 0 and "score.json written again from" in again.stderr, again.stderr
                out = run_script("sweep.py", str(folder), "--out", str(tmp_path / "again" / folder.name))
                assert (tmp_path / "again" / folder.name / "sweep.csv").read_text() == wanted
                outcome += ", repaired by the rerun"
            outcomes[f"{rel.replace(job + '/', '').replace('.hydra/overrides', 'overrides')} {name}"] = outcome
    assert outcomes == {
        **{f"multirun.yaml {n}": "same" for n in ("deleted", "truncated", "garbage")},
        "overrides.yaml deleted": "refused",
        "overrides.yaml truncated": "same",
        "overrides.yaml garbage": "refused",
        "overrides.yaml swapped": "refused",  # job 1's seed over job 0's run: never counted as job 1's
        "score.json deleted": "unfinished, repaired by the rerun",
        **{f"score.json {n}": "refused, repaired by the rerun" for n in ("truncated", "garbage", "swapped")},
        **{f"progress.csv {n}": "refused" for n in SWEEP_DAMAGES},
        "config.yaml deleted": "same",
        "config.yaml truncated": "same",
        "config.yaml garbage": "refused",
        "config.yaml swapped": "refused",
        **{f".hydra/config.yaml {n}": "same" for n in SWEEP_DAMAGES},  # Hydra's copy: read by no table
    }, outcomes


def test_a_job_folder_is_named_by_the_values_its_job_set():
    from searchrl.train.schema import job_name

    name = job_name(3, ["+experiment=term/b", "algo.learning_rate=0.001", "seed=1", "progress_bar=false",
                        "logger.mode=offline", "hydra.launcher.n_jobs=2"])  # fmt: skip
    assert name == "3_experiment=term-b,algo.learning_rate=0.001,seed=1"  # one folder level, what it trains
    assert job_name(0, []) == "0"
    long = job_name(1, [f"grid.world_sizes=[{','.join(['160'] * 60)}]"])
    assert len(long) == 160 and long != job_name(1, [f"grid.world_sizes=[{','.join(['160'] * 61)}]"])
