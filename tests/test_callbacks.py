"""The training app's callbacks, in process and without training: team metrics per rollout, the checkpoint schedule
and what it keeps, the stop a signal asks for (tests/test_preemption.py signals a real training), the validation
schedule and the hyperparameters a run shows TensorBoard."""

from __future__ import annotations

import signal
from dataclasses import asdict
from pathlib import Path
from types import SimpleNamespace

import pytest
from hydra import compose, initialize_config_dir

import searchrl.train.callbacks as callbacks
from searchrl.shared_schema import CONF_DIR
from searchrl.train.callbacks import (
    AtomicCheckpointCallback,
    HParamsCallback,
    Preemption,
    TeamMetricsCallback,
    ValidationCallback,
    checkpoints,
    run_hparams,
)
from searchrl.train.logs import log_digest
from searchrl.train.plan import make_plan
from searchrl.train.schema import register_configs


class _Logger:
    """SB3's logger as the callbacks use it: means recorded per key (team metrics); values recorded, with what they
    exclude, then dumped as one row at a step (validation, HParams)."""

    def __init__(self) -> None:
        self.means: dict[str, float] = {}
        self.row: dict[str, object] = {}
        self.excluded: dict[str, tuple[str, ...]] = {}
        self.dumped: list[tuple[int, dict[str, object]]] = []

    def record_mean(self, key: str, value: float) -> None:
        self.means[key] = value

    def record(self, key: str, value: object, exclude: tuple[str, ...] | None = None) -> None:
        self.row[key] = value
        if exclude is not None:
            self.excluded[key] = exclude

    def dump(self, step: int) -> None:
        self.dumped.append((step, self.row))
        self.row = {}


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
    (tmp_path / "progress.csv").write_text("time/total_timesteps,val/F\n128,1.5\n256,2.5\n384,3.5\n")
    callback._on_training_end()  # with the digest of the log's rows before its step
    assert (folder / "step_384.zip").read_text() == f"384 {{'id': 'r'}} {log_digest(tmp_path / 'progress.csv', 384)}"
    assert log_digest(tmp_path / "progress.csv", 384) != log_digest(tmp_path / "progress.csv", 385)
    assert saved[-1] == 384 and sorted(step for step, _ in checkpoints(folder)) == [320, 384]
    assert AtomicCheckpointCallback(folder, 100).keep == 3  # by default
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


@pytest.fixture
def episodes(monkeypatch) -> list[tuple]:
    """Validation's episodes replaced: each call's arguments kept (the policy as the step its weights are at) and a
    found fraction of that step / 1000 returned (the random walk's: 0.1)."""
    calls: list[tuple] = []

    def run_episodes(config, n_worlds, seed, model, deterministic=False, scenario=None):
        step = None if model is None else model.num_timesteps
        calls.append((config, n_worlds, seed, step, deterministic, scenario))
        return {"found_fraction": 0.1 if model is None else step / 1000, "F": 2.0}

    monkeypatch.setattr(callbacks, "run_episodes", run_episodes)
    return calls


def _validation(start: int, every: int, total: int, at_start: bool = False, preemption: Preemption | None = None):
    callback = ValidationCallback("world", "scenario", every, n_worlds=16, seed=7, deterministic=True,
                                  at_start=at_start, preemption=preemption)  # fmt: skip
    # rollouts of 4 steps of 8 agent-steps (32 agent-steps) toward a budget of `total`
    callback.model = SimpleNamespace(num_timesteps=start, n_steps=4, n_envs=8, _total_timesteps=total, logger=_Logger())
    callback.num_timesteps = start
    callback._init_callback()
    callback._on_training_start()
    return callback


def _train(callback: ValidationCallback, rollouts: int) -> None:
    """SB3's order: a rollout starts, then each step adds n_envs agent-steps and calls the callback."""
    for _ in range(rollouts):
        callback._on_rollout_start()
        for _ in range(callback.model.n_steps):
            callback.num_timesteps = callback.model.num_timesteps = callback.num_timesteps + callback.model.n_envs
            assert callback._on_step() is True


def test_validation_runs_past_each_multiple_but_not_in_the_last_rollout_and_once_at_the_end(episodes):
    callback = _validation(0, every=100, total=320)
    assert episodes == [("world", 16, 7, None, False, "scenario")]  # the random walk's level, once
    _train(callback, 10)
    # past 100 and 200; past 300 falls in the last rollout (288-320), whose end is the final validation's step
    assert [call[3] for call in episodes[1:]] == [104, 200]
    assert all(call[:3] == ("world", 16, 7) and call[4:] == (True, "scenario") for call in episodes[1:])
    callback._on_training_end()
    assert [call[3] for call in episodes[1:]] == [104, 200, 320]
    assert callback.model.logger.dumped == [(320, {"val/found_fraction": 0.32, "val/F": 2.0,
                                                   "val/random_found_fraction": 0.1,
                                                   "time/total_timesteps": 320})]  # fmt: skip


def test_validation_at_the_start_only_of_a_fresh_run_on_a_resumed_runs_schedule_or_never(episodes):
    fresh = _validation(0, every=100, total=1000, at_start=True)
    assert [call[3] for call in episodes] == [None, 0]
    start_row = {"val/found_fraction": 0.0, "val/F": 2.0, "val/random_found_fraction": 0.1, "time/total_timesteps": 0}
    assert fresh.model.logger.dumped == [(0, start_row)]
    episodes.clear()
    resumed = _validation(250, every=100, total=1000, at_start=True)  # nothing at its start; next past 300
    _train(resumed, 2)  # steps 258, 266, ..., 314
    assert [call[3] for call in episodes] == [None, 306] and resumed.model.logger.dumped == []
    episodes.clear()
    never = _validation(0, every=0, total=1000)  # every=0: the final validation only
    _train(never, 5)
    never._on_training_end()
    assert [call[3] for call in episodes] == [None, 160]
    assert ValidationCallback("world", "scenario", 0, 1, 0, False).at_start is False  # by default
    episodes.clear()
    each = _validation(0, every=1, total=64)  # every=1: at each step but in the last rollout
    _train(each, 2)
    assert [call[3] for call in episodes] == [None, 8, 16, 24, 32]


def test_a_stopped_run_leaves_the_final_validation_to_its_real_end(episodes):
    preemption = Preemption()
    callback = _validation(0, every=1000, total=320, preemption=preemption)
    _train(callback, 2)
    preemption.stopped = True
    callback._on_training_end()
    assert [call[3] for call in episodes] == [None] and callback.model.logger.dumped == []


def test_hparams_are_written_to_tensorboard_alone_linked_to_the_found_fractions():
    hparams = {"algo.gamma": 0.99, "model": "b"}
    callback = HParamsCallback(hparams)
    callback.model = SimpleNamespace(logger=_Logger())
    callback._on_training_start()
    value = callback.model.logger.row["hparams"]
    assert value.hparam_dict == hparams
    assert value.metric_dict == {"val/found_fraction": 0.0, "team/found_fraction": 0.0}
    assert callback.model.logger.excluded == {"hparams": ("stdout", "log", "json", "csv")}
    assert callback._on_step() is True


@pytest.mark.parametrize(
    "overrides, chosen",
    [
        (["+experiment=rl/b", "seed=3"],
         {"model": "b", "network.extractor": "search_cnn", "network.lstm_hidden_size": 128, "critic": "shared",
          "imitation.teacher": "none", "imitation.rl_weight": 0.0, "imitation.rl_schedule": "constant",
          "reward": "paper", "scenario": "paper", "seed": 3, "total_timesteps": 7000064}),
        (["+experiment=term/b", "critic=true_state", "imitation.rl_schedule=anneal"],
         {"model": "b", "network.extractor": "search_cnn", "network.lstm_hidden_size": 128, "critic": "true_state",
          "imitation.teacher": "greedy_target", "imitation.rl_weight": 0.5, "imitation.rl_schedule": "anneal",
          "reward": "paper", "scenario": "paper", "seed": 0, "total_timesteps": 3010560}),
    ],
)  # fmt: skip
def test_a_runs_hparams_are_its_algorithms_scalars_and_the_choices_a_sweep_varies(overrides, chosen):
    register_configs()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        settings = make_plan(compose(config_name="train", overrides=overrides)).settings
    assert run_hparams(settings, "paper") == {**{f"algo.{k}": v for k, v in asdict(settings.algo).items()}, **chosen}
