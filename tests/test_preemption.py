"""Preemption: SIGTERM or SIGINT to a real training process stops it with a checkpoint of its last update, an exit
status a requeueing launcher reads (128 + the signal), and a log that a resume continues with every step once."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from sb3_contrib import RecurrentPPO

from searchrl.train.callbacks import checkpoints

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
# A tiny run that would take hours: only the signal ends it; no periodic checkpoint (checkpoint_every beyond it).
TINY = ["+model=b", "env.n_worlds=2", "env.world.n_agents=4", "env.world.world_size=[12,20]",
        "env.world.n_targets=[2,4]", "env.world.n_distributions=[4,8]", "network=small", "algo.batch_size=128",
        "algo.n_steps=32", "validation.every=0", "progress_bar=false", "threads=1"]  # fmt: skip
ROLLOUT = 32 * 2 * 4  # algo.n_steps × K × N agent-steps


STARTED: list[subprocess.Popen] = []


@pytest.fixture(autouse=True)
def _end_every_training():
    """Whatever a test does (a failed assertion before its signal, a timeout), no training it started outlives it:
    TINY runs train for hours unless signalled."""
    yield
    while STARTED:
        process = STARTED.pop()
        if process.poll() is None:
            process.kill()
            process.communicate(timeout=60)


def _train(run: Path, *overrides: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "searchrl.train", *overrides, f"hydra.run.dir={run}"]
    STARTED.append(subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    return STARTED[-1]


def _rows(run: Path) -> list[int]:
    """The steps of progress.csv's rows ([] while the run has written none, or is writing its first)."""
    try:
        return pd.read_csv(run / "progress.csv")["time/total_timesteps"].tolist()
    except (FileNotFoundError, pd.errors.EmptyDataError):
        return []


@pytest.mark.parametrize("signum", [signal.SIGTERM, pytest.param(signal.SIGINT, marks=pytest.mark.slow)])
def test_a_signal_checkpoints_the_last_update_and_a_resume_logs_every_step_once(tmp_path, signum):
    run = tmp_path / "run"
    process = _train(run, *TINY, "total_timesteps=100000000", "checkpoint_every=100000000")
    deadline = time.monotonic() + 240
    while len(_rows(run)) < 3 and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert process.poll() is None, process.communicate()[1][-3000:]
    process.send_signal(signum)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 128 + signum, err[-3000:]
    saved = checkpoints(run / "checkpoints")
    assert len(saved) == 1 and not (run / "model.zip").exists()  # stopped, not finished
    step, path = saved[0]
    assert step % ROLLOUT == 0 and step > 0 and RecurrentPPO.load(path).num_timesteps == step
    assert f"stopped by {signal.Signals(signum).name} at {step} agent-steps" in err and "Traceback" not in err
    assert _rows(run) == list(range(ROLLOUT, step + 1, ROLLOUT))  # each finished update's row, none past it
    resumed = _train(tmp_path / "log", f"resume={run}", f"total_timesteps={step + 2 * ROLLOUT}")
    _, err = resumed.communicate(timeout=300)
    assert resumed.returncode == 0, err[-3000:]
    assert _rows(run)[:-1] == list(range(ROLLOUT, step + 2 * ROLLOUT + 1, ROLLOUT))  # then the final validation's
    assert RecurrentPPO.load(run / "model.zip").num_timesteps == step + 2 * ROLLOUT


@pytest.mark.slow
def test_kill_9_at_any_moment_then_resume_logs_every_step_once_and_in_order(tmp_path):
    """A clone-then-RL run killed with SIGKILL at several moments (start-up, the clone, RL), resumed after each kill,
    then to its end: progress.csv holds every step once and in order (the final validation's row repeats the last
    step), and the final model has trained the whole budget."""
    run = tmp_path / "run"
    budget = 40 * ROLLOUT
    first = [*TINY, f"total_timesteps={budget}", f"checkpoint_every={4 * ROLLOUT}", "imitation.teacher=greedy_target",
             "imitation.episodes=2", "imitation.epochs=2"]  # fmt: skip
    for attempt, delay in enumerate([1.0, 6.0, 9.0, 12.0, 15.0]):
        started = run.joinpath("config.yaml").exists() or any(checkpoints(run / "checkpoints"))
        process = _train(tmp_path / f"log{attempt}", f"resume={run}") if started else _train(run, *first)
        time.sleep(delay)
        process.kill()
        process.communicate(timeout=60)
    last = _train(tmp_path / "last", f"resume={run}") if run.joinpath("config.yaml").exists() else _train(run, *first)
    _, err = last.communicate(timeout=600)
    assert last.returncode == 0, err[-3000:]
    steps = _rows(run)
    assert steps[-1] == steps[-2] == budget and steps[:-1] == sorted(set(steps[:-1])), steps
    assert RecurrentPPO.load(run / "model.zip").num_timesteps == budget
