"""The training app's callbacks, in process and without training: team metrics per rollout, the checkpoint schedule
and what it keeps, the stop a signal asks for (tests/test_preemption.py signals a real training)."""

from __future__ import annotations

import signal
from pathlib import Path
from types import SimpleNamespace

import pytest

import searchrl.train.callbacks as callbacks
from searchrl.train.callbacks import AtomicCheckpointCallback, Preemption, TeamMetricsCallback, checkpoints


class _Logger:
    """SB3's logger as the callbacks use it: record_mean, kept per key."""

    def __init__(self) -> None:
        self.means: dict[str, float] = {}

    def record_mean(self, key: str, value: float) -> None:
        self.means[key] = value


def test_team_metrics_are_the_means_over_the_rollouts_ended_episodes_and_start_afresh():
    callback, logger = TeamMetricsCallback(), _Logger()
    callback.model = SimpleNamespace(logger=logger)  # BaseCallback.logger is the model's
    rollouts = [
        [[{}, {"team_metrics": {"F": 2.0, "L": 10.0}}], [{"team_metrics": {"F": 4.0, "L": 30.0}}, {"other": 1}]],
        [[{"team_metrics": {"F": 7.0, "L": 5.0}}]],  # the next rollout: its own episodes only
        [[{}, {}]],  # no episode ended: nothing logged
    ]
    expected = [{"team/F": 3.0, "team/L": 20.0, "team/episodes": 2}, {"team/F": 7.0, "team/L": 5.0, "team/episodes": 1},
                {}]  # fmt: skip
    for steps, means in zip(rollouts, expected, strict=True):
        logger.means.clear()
        callback._on_rollout_start()
        for infos in steps:
            callback.locals = {"infos": infos}
            assert callback._on_step() is True
        callback._on_rollout_end()
        assert logger.means == means


def test_checkpoints_lists_the_complete_ones_only(tmp_path):
    for name in ("step_512.zip", "step_1024.zip", ".step_2048.zip.tmp", "step_x.zip", "step_64.zip.bak", "a.zip"):
        (tmp_path / name).write_bytes(b"")
    assert sorted(checkpoints(tmp_path)) == [(512, tmp_path / "step_512.zip"), (1024, tmp_path / "step_1024.zip")]


@pytest.fixture
def saved(monkeypatch) -> list[int]:
    """Replace the model's writing by a file of its step (the schedule is under test, not SB3's zip)."""
    steps: list[int] = []

    def save_model(model, path: Path, run: dict, log: str | None) -> Path:
        steps.append(model.num_timesteps)
        path.write_text(f"{model.num_timesteps} {run} {log}")
        return path

    monkeypatch.setattr(callbacks, "save_model", save_model)
    return steps


def _callback(folder: Path, start: int, every: int, keep: int = 3, preemption: Preemption | None = None):
    callback = AtomicCheckpointCallback(folder, every, keep=keep, preemption=preemption, run={"id": "r"})
    callback.model = SimpleNamespace(num_timesteps=start)
    callback.num_timesteps = start
    callback._init_callback()
    return callback


def _rollout_starts_at(callback: AtomicCheckpointCallback, step: int) -> None:
    callback.num_timesteps = callback.model.num_timesteps = step
    callback._on_rollout_start()


def test_checkpoints_are_taken_at_the_first_rollout_start_past_each_multiple_and_the_newest_kept(tmp_path, saved):
    folder = tmp_path / "checkpoints"
    folder.mkdir()
    callback = _callback(folder, 0, every=100, keep=2)
    for step in (64, 128, 192, 256, 320, 384):
        _rollout_starts_at(callback, step)
    assert saved == [128, 256, 320]
    assert sorted(step for step, _ in checkpoints(folder)) == [256, 320]
    assert (folder / "step_320.zip").read_text() == "320 {'id': 'r'} None"  # the run's identity, no log yet
    callback._on_training_end()
    assert saved[-1] == 384 and sorted(step for step, _ in checkpoints(folder)) == [320, 384]
    resumed = _callback(folder, 250, every=100)  # a resume at 250: the next multiple is 300
    _rollout_starts_at(resumed, 288)
    _rollout_starts_at(resumed, 300)
    assert saved[-1] == 300


def test_a_signal_stops_before_the_next_rollout_and_the_checkpoint_holds_only_trained_steps(tmp_path, saved):
    preemption = Preemption()
    callback = _callback(tmp_path, 0, every=10_000, preemption=preemption)
    _rollout_starts_at(callback, 0)
    assert callback._on_step() is True and not callback.stopped
    preemption.signal = signal.SIGTERM  # caught during the rollout or its update
    _rollout_starts_at(callback, 64)  # that update is done: stop, no checkpoint yet
    assert callback.stopped and preemption.stopped and callback._on_step() is False and saved == []
    callback.num_timesteps = callback.model.num_timesteps = 65  # the one step collected before the stop
    callback._on_training_end()
    assert saved == [64] and callback.model.num_timesteps == 64 and (tmp_path / "step_64.zip").exists()


def test_the_first_signal_is_kept_a_second_interrupt_ends_at_once_and_handlers_are_restored(capsys):
    before = {signum: signal.getsignal(signum) for signum in (signal.SIGTERM, signal.SIGINT)}
    with Preemption() as preemption:
        assert all(signal.getsignal(signum) == preemption._handle for signum in before)
        preemption._handle(signal.SIGTERM, None)
        preemption._handle(signal.SIGTERM, None)  # a second SIGTERM changes nothing
        assert preemption.signal == signal.SIGTERM
        assert capsys.readouterr().err == "SIGTERM: stopping after this rollout's update, with a checkpoint\n"
        with pytest.raises(KeyboardInterrupt):
            preemption._handle(signal.SIGINT, None)
    assert {signum: signal.getsignal(signum) for signum in before} == before
