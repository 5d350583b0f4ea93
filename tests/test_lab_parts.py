"""The research parts under analysis/ that the lab's long trainings use: the team reward registered through
`extensions`, and carrying a training to another machine through runs/lab/ (analysis/carry_runs.py)."""

from __future__ import annotations

import json
import shutil
import sys
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from searchrl.envs.rewards import make_reward
from searchrl.policies.slim import ROLLOUT_STATE, is_slim, weights_sha256
from searchrl.world.config import WorldConfig
from searchrl.world.step import StepResult
from tests.test_train import TINY, _compose, _run

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "analysis"))
import carry_runs  # noqa: E402  (analysis/ is no package)
import team_reward  # noqa: E402,F401  (registers `team_found` and `own_found`)


def _result(found: np.ndarray) -> StepResult:
    k, n = found.shape
    return StepResult(reward=np.full((k, n), 7.0, np.float32), terminated=np.zeros(k, bool),
                      truncated=np.zeros(k, bool), collided=np.zeros((k, n), bool), targets_found=found,
                      info_collected=np.ones((k, n)), comm_gain=np.ones((k, n)),
                      comm_pairs=np.zeros(k, np.int64))  # fmt: skip


def test_the_team_reward_pays_every_agent_its_worlds_finds_and_nothing_else():
    found = np.array([[0, 2, 0], [0, 0, 0], [1, 1, 3]], np.int64)
    reward = make_reward("team_found")(WorldConfig(), _result(found))
    assert reward.dtype == np.float32 and reward.shape == (3, 3)
    assert reward.tolist() == [[2, 2, 2], [0, 0, 0], [5, 5, 5]]  # the paper's reward (7), information, ignored
    assert reward.flags.writeable  # a fresh array, not a read-only broadcast view


def test_the_own_reward_pays_each_agent_its_own_finds_and_nothing_else():
    found = np.array([[0, 2, 0], [1, 1, 3]], np.int64)
    reward = make_reward("own_found")(WorldConfig(), _result(found))
    assert reward.dtype == np.float32 and reward.tolist() == [[0, 2, 0], [1, 1, 3]]


@pytest.mark.app
def test_a_carried_run_holds_its_newest_checkpoint_and_resumes_elsewhere(tmp_path):
    run = tmp_path / "train" / "tiny"
    _run(run, ["+model=b", *TINY])
    whole = pd.read_csv(run / "progress.csv")["time/total_timesteps"].tolist()
    (run / "checkpoints" / "step_2048.zip").unlink()  # as if stopped after its checkpoint at 1024: rows past it stay
    (run / "model.zip").unlink()
    for path in (run / "checkpoints").glob("*.zip"):  # searchrl's checkpoints leave out the rollout in progress
        assert not set(json.loads(zipfile.ZipFile(path).read("data"))) & set(ROLLOUT_STATE)

    lab = tmp_path / "lab"
    carried = carry_runs.carry(run, lab)
    assert carried == lab / "tiny"
    assert sorted(p.name for p in (carried / "checkpoints").iterdir()) == ["step_1024.zip"]
    assert weights_sha256(carried / "checkpoints" / "step_1024.zip") == weights_sha256(run / "checkpoints" /
                                                                                     "step_1024.zip")  # fmt: skip
    assert not (carried / "tensorboard").exists() and (carried / "config.yaml").read_bytes() == (
        run / "config.yaml").read_bytes()  # fmt: skip

    elsewhere = tmp_path / "other_machine" / "tiny"
    shutil.copytree(carried, elsewhere)
    from searchrl.train.app import train

    overrides = [f"resume={elsewhere}", "total_timesteps=2048"]
    train(_compose(overrides), elsewhere / "resumed", overrides)
    steps = pd.read_csv(elsewhere / "progress.csv")["time/total_timesteps"].tolist()
    assert steps == whole  # the rows past 1024 replaced, not doubled
    assert (elsewhere / "model.zip").is_file()

    carried_again = carry_runs.carry(elsewhere, lab)  # the newer checkpoint replaces the older
    assert sorted(p.name for p in (carried_again / "checkpoints").iterdir()) == ["step_2048.zip"]
    assert not is_slim(carried_again / "checkpoints" / "step_2048.zip")  # Adam's moments carried

    assert carry_runs.main(["--to", str(tmp_path / "gpu"), "--without-moments", str(elsewhere)]) == 0
    light = tmp_path / "gpu" / "tiny" / "checkpoints" / "step_2048.zip"
    assert is_slim(light) and weights_sha256(light) == weights_sha256(elsewhere / "checkpoints" / "step_2048.zip")


@pytest.mark.parametrize("argv", [[], ["--to"], ["--to", "lab"], ["--moments", "run"]])
def test_the_carry_command_refuses_what_it_does_not_know_in_one_line(argv, capsys):
    assert carry_runs.main(argv) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_carrying_a_folder_without_checkpoints_is_refused_in_one_line(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "config.yaml").write_text("seed: 0\n")
    with pytest.raises(SystemExit, match=r"holds no checkpoints/step_<n>.zip"):
        carry_runs.carry(tmp_path / "run", tmp_path / "lab")
