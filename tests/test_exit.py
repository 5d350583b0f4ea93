"""Expert iteration's two experiments (analysis/exit_labels.py, analysis/exit_train.py): the planner's move values
on the student's own episodes, and a student fitted to softmax(prior + values / tau) that evaluates as any run."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import torch

from searchrl.evaluate.grid import Cell
from searchrl.policies.checkpoint import checkpoint_config, load_actor, load_checkpoint
from searchrl.world.config import WorldConfig
from tests.registries import isolated_registries
from tests.test_faults import REFERENCE_B

STUDENT = str(REFERENCE_B.parent / "term" / "b" / "model.zip")

pytestmark = pytest.mark.app  # runs the planner and trains a network: not in the fast layer (docs/testing.md)


@pytest.fixture
def exit_parts():
    """(exit_labels, exit_train), the planner's controller registered for this test only."""
    with isolated_registries("analysis"):
        yield importlib.import_module("analysis.exit_labels"), importlib.import_module("analysis.exit_train")


def test_the_targets_keep_the_prior_where_moves_tie_and_lean_to_the_better_move(exit_parts):
    exit_train = exit_parts[1]
    prior = torch.log_softmax(torch.tensor([[2.0, 0.0, 0.0, 0.0, -1.0]]), dim=-1)
    tied = exit_train.targets(np.full((1, 5), 0.7, np.float32), 0.01, prior)
    torch.testing.assert_close(tied, prior.exp())
    lean = exit_train.targets(np.array([[0.70, 0.72, 0.70, 0.70, 0.70]], np.float32), 0.01, prior)
    assert lean[0, 1] / lean[0, 2] == pytest.approx(np.exp(2.0), rel=1e-3)  # 0.02 targets better: e² the odds
    alone = exit_train.targets(np.array([[0.0, 0.01, 0.0, 0.0, 0.0]], np.float32), 0.01, None)
    assert alone[0, 1] / alone[0, 0] == pytest.approx(np.e, rel=1e-4)


def test_labels_then_a_student_that_evaluates_as_a_run(tmp_path, capsys, exit_parts):
    exit_labels, exit_train = exit_parts
    labels, student = tmp_path / "labels", tmp_path / "student"
    settings = '{"horizon": 2}'
    args = ["--student", STUDENT, "--out", str(labels), "--shards", "1", "--worlds", "1", "--cells", "n40_N1"]
    assert exit_labels.main([*args, "--settings", settings]) == 0
    data = np.load(labels / "shard_0000.npz")
    steps = int(data["mask"].sum())
    assert data["maps"].shape[:2] == data["values"].shape[:2] == data["mask"].shape and 0 < steps <= 256
    values = data["values"][data["mask"]]
    assert np.isfinite(values).all() and values.shape[1] == 5 and (values.max(1) >= values.min(1)).all()
    before = (labels / "shard_0000.npz").stat().st_mtime_ns
    assert exit_labels.main([*args, "--settings", settings]) == 0  # a rerun keeps the shard it finds
    assert (labels / "shard_0000.npz").stat().st_mtime_ns == before
    assert exit_train.main(["--labels", str(labels), "--init", STUDENT, "--out", str(student), "--epochs", "1"]) == 0
    assert "epoch 1: held-out cross-entropy" in capsys.readouterr().err
    world = WorldConfig.from_dict(checkpoint_config(student / "model.zip")[0])
    actor = load_actor(student / "model.zip", world)
    maps = np.zeros((1, *data["maps"].shape[2:]), np.float32)
    logits, _ = actor.logits(maps, np.zeros((1, 3), np.float32), actor.initial_state(1))
    assert logits.shape == (1, 5) and np.isfinite(logits).all()


def test_a_bad_cell_is_one_line(exit_parts):
    exit_labels = exit_parts[0]
    with pytest.raises(ValueError, match=r"--cells: 'n50_N2' is not allowed"):
        exit_labels.parse_cells("n40_N2,n50_N2")
    assert exit_labels.parse_cells("n80_N4") == [Cell(80, 4, 16, 32)]


def test_a_whole_map_student_records_its_map_and_opens_its_gate(tmp_path, exit_parts):
    """A student whose network reads the coarse whole belief map (own_map_cnn) has that map in every labelled step,
    and its training reads it: the branch's gate moves at the branch's own learning rate."""
    from tests.test_faults import TINY, _compose, train

    exit_labels, exit_train = exit_parts
    overrides = [*TINY, "network.extractor=own_map_cnn", "total_timesteps=1024"]
    model = train(_compose("train", overrides), tmp_path / "run", overrides)
    labels = tmp_path / "labels"
    args = ["--student", str(model), "--out", str(labels), "--shards", "1", "--worlds", "2", "--cells", "n40_N2"]
    assert exit_labels.main([*args, "--settings", '{"horizon": 2}']) == 0  # 4 sequences: 3 to train on
    data = np.load(labels / "shard_0000.npz")
    assert data["part_own_map"].shape == (*data["mask"].shape, 3, 16, 16)
    assert data["part_own_map"][data["mask"]].max() > 0  # the agent's own cell at least
    out = tmp_path / "student"
    argv = ["--labels", str(labels), "--init", str(model), "--out", str(out), "--epochs", "1", "--branch-lr", "0.01"]
    assert exit_train.main(argv) == 0
    gates = [load_checkpoint(m, device="cpu").policy.features_extractor.gate.item() for m in (model, out / "model.zip")]
    assert abs(gates[1] - gates[0]) > 1e-3  # an Adam step at 0.01, where the rest moves at 1e-4
