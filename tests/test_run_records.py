"""What a checkpoint's run recorded, read in process: its world, algorithm and model, its training scenario, the
suite folder named after it, and the view and moves its policy was trained for (the apps read them in their own
processes in tests/test_evaluate.py and test_suite.py)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest
from omegaconf import OmegaConf

from searchrl.evaluate.suite import suite_default_dir
from searchrl.policies.checkpoint import checkpoint_config, load_actor, training_scenario
from searchrl.world.config import WorldConfig

ROOT = Path(__file__).resolve().parents[1]

# A run's config.yaml as the training app writes it, interpolations included (resolved when read).
RECORD = {
    "size": 40,
    "env": {"world": {"world_size": ["${size}", "${size}"], "n_agents": 8}},
    "algo": {"name": "recurrent_ppo"},
    "model": {"name": "b"},
}


def _run(folder: Path, record: dict) -> list[Path]:
    """A run folder holding `record` as its config.yaml, a model.zip and one checkpoint (their bytes unread)."""
    (folder / "checkpoints").mkdir(parents=True)
    OmegaConf.save(OmegaConf.create(record), folder / "config.yaml")
    files = [folder / "model.zip", folder / "checkpoints" / "step_512.zip"]
    for path in files:
        path.write_bytes(b"zip")
    return files


def test_a_checkpoints_config_is_its_runs_world_algorithm_and_model(tmp_path):
    for path in _run(tmp_path / "b", RECORD):
        assert checkpoint_config(path) == ({"world_size": [40, 40], "n_agents": 8}, "recurrent_ppo", "b")
    modelless = {key: value for key, value in RECORD.items() if key != "model"}
    for path in _run(tmp_path / "other", modelless):
        assert checkpoint_config(path)[2] == "unknown"


@pytest.mark.parametrize("scenario", [None, {"name": "walls", "obstacles": {"density": 0.2, "side": "${size}"}}])
def test_a_checkpoints_training_scenario_is_its_runs_or_none(tmp_path, scenario):
    record = RECORD if scenario is None else {**RECORD, "scenario": scenario}
    expected = None if scenario is None else {"name": "walls", "obstacles": {"density": 0.2, "side": 40}}
    for path in _run(tmp_path / "run", record):
        assert training_scenario(path) == expected


def test_a_suites_default_folder_names_the_rule_or_the_policys_run(tmp_path):
    rule = SimpleNamespace(checkpoint=None, controller=SimpleNamespace(name="greedy_target"))
    assert suite_default_dir(rule, "obstacles") == Path("runs/suite/obstacles/greedy_target")
    model = tmp_path / "runs" / "train" / "b" / "model.zip"
    policy = SimpleNamespace(checkpoint=str(model), controller=SimpleNamespace(name="policy"))
    assert suite_default_dir(policy, "prior_error") == Path("runs/suite/prior_error/policy/train/b")


def test_a_policy_is_refused_in_a_world_it_cannot_see_or_move_in():
    model = ROOT / "runs" / "reference" / "diagonal" / "model.zip"  # 8 moves, 5 channels
    assert load_actor(model, WorldConfig(diagonal=True), optimize=False).n_actions == 9
    with pytest.raises(ValueError) as moves:
        load_actor(model, WorldConfig())
    assert str(moves.value) == f"checkpoint={str(model)!r} acts with 9 actions but the world has 5"
    with pytest.raises(ValueError) as view:
        load_actor(model, WorldConfig(diagonal=True, belief_age=1.0, belief_age_channel=True))
    assert str(view.value) == (
        f"checkpoint={str(model)!r} sees a (5, 11, 11) field of view but the world shows (6, 11, 11) (channels, "
        "side, side: fov and belief_age_channel must be the checkpoint's)"
    )
