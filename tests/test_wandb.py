"""The run's logs beyond progress.csv: with `logger=wandb` every row the run logs goes to one W&B run too, at the same
agent-steps, and a resumed segment continues that run (offline, with no network, wandb writes it under
<run>/wandb/); TensorBoard holds the run's settings as hyperparameters."""

from __future__ import annotations

import sys
import types

import pandas as pd
import pytest

from searchrl.multirun import exits
from tests.test_train import TINY, _compose, _run

pytestmark = pytest.mark.app  # trains tiny runs (docs/testing.md)

SHORT = [o for o in TINY if not o.startswith(("total_timesteps", "validation.every"))]
SHORT += ["total_timesteps=1024", "validation.every=512"]


class FakeWandb(types.ModuleType):
    """A stand-in for the wandb package that records what a run would send."""

    def __init__(self) -> None:
        super().__init__("wandb")
        self.inits, self.rows, self.finished = [], [], 0

    def init(self, **settings):
        self.inits.append(settings)
        module = self

        class Run:
            def log(self, values, step):
                module.rows.append((step, dict(values)))

            def finish(self):
                module.finished += 1

        return Run()


def _tensorboard_hparams(folder):
    """The hyperparameters of the first TensorBoard event file in `folder` (its HParams tab's session)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    from tensorboard.plugins.hparams import plugin_data_pb2

    events = EventAccumulator(str(sorted(folder.iterdir())[0]))
    events.Reload()
    content = events.PluginTagToContent("hparams")["_hparams_/session_start_info"]
    return plugin_data_pb2.HParamsPluginData.FromString(content).session_start_info.hparams


def test_every_logged_row_goes_to_one_wandb_run_that_a_resume_continues(tmp_path, monkeypatch):
    """Every row the run logs goes to one W&B run, at its agent-step, and a resume continues that run; TensorBoard
    holds the run's settings (algo.*, model, network, critic, teacher term, scenario, seed) as its hyperparameters,
    linked to the found fractions, and progress.csv gets no column for them."""
    fake = FakeWandb()
    monkeypatch.setitem(sys.modules, "wandb", fake)
    _run(tmp_path, ["+model=b", *SHORT, "logger=wandb", "checkpoint_every=512", "algo.learning_rate=0.0007"])
    progress = pd.read_csv(tmp_path / "progress.csv")
    assert "hparams" not in progress.columns  # TensorBoard's alone
    hparams = _tensorboard_hparams(tmp_path / "tensorboard")
    assert hparams["algo.learning_rate"].number_value == pytest.approx(0.0007)
    assert (hparams["model"].string_value, hparams["critic"].string_value) == ("b", "shared")
    assert hparams["scenario"].string_value == "paper" and hparams["seed"].number_value == 0
    validations = progress.dropna(subset=["val/found_fraction"])
    sent = [(step, row["val/found_fraction"]) for step, row in fake.rows if "val/found_fraction" in row]
    assert sent == list(zip(validations["time/total_timesteps"], validations["val/found_fraction"], strict=True))
    assert [step for step, _ in fake.rows] == progress["time/total_timesteps"].tolist()  # row for row
    first = fake.inits[0]
    assert (first["mode"], first["project"], first["name"], first["resume"]) == ("offline", "searchrl",
                                                                                 tmp_path.name, "allow")  # fmt: skip
    assert first["config"]["seed"] == 0 and fake.finished == 1
    more = [f"resume={tmp_path}", "total_timesteps=1536"]
    from searchrl.train.app import train

    train(_compose(more), tmp_path / "r", more)
    assert len(fake.inits) == 2 and fake.inits[1]["id"] == first["id"]  # the same W&B run, continued
    assert fake.rows[-1][0] == 1536


@pytest.mark.slow  # the wandb package itself, offline: its service process takes a while to start and end
def test_wandb_offline_writes_its_run_under_the_run_folder(tmp_path, monkeypatch):
    pytest.importorskip("wandb")  # installed with '.[track]', which '.[dev]' includes
    monkeypatch.setenv("WANDB_SILENT", "true")
    _run(tmp_path, ["+model=b", *SHORT, "logger=wandb"])
    runs = list((tmp_path / "wandb").glob("offline-run-*/run-*.wandb"))
    assert len(runs) == 1 and runs[0].stat().st_size > 0


@pytest.mark.parametrize("bad, needle", [("logger.mode=cloud", "logger.mode='cloud' is not allowed: one of offline, "
                                                               "online")])  # fmt: skip
def test_a_bad_logger_setting_is_refused_before_any_file(tmp_path, capsys, bad, needle):
    with pytest.raises(SystemExit) as stop, exits():
        _run(tmp_path / "run", ["+model=b", *SHORT, "logger=wandb", bad])
    assert stop.value.code == 2 and needle in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
