"""The CPU's inference paths (searchrl/policies/actor.py): `inference=onnx` (ONNX Runtime) is not bit for bit torch's
path, so it is checked against it on the same maps: logits to rounding, the greedy actions of every shipped policy
on the states torch's own episodes visit, and the paired found fractions of sampled episodes on a small grid; and an
evaluation folder records its path and refuses cells of another."""

from __future__ import annotations

import numpy as np
import pytest
from omegaconf import OmegaConf

from searchrl.controllers.factory import policy_factory
from searchrl.controllers.policy import PolicyController
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.paired import bootstrap_mean_ci
from searchrl.evaluate.runner import run_cell
from searchrl.policies.actor import Actor, check_inference
from searchrl.policies.checkpoint import checkpoint_config, load_actor, load_checkpoint
from searchrl.world.config import WorldConfig
from tests.test_faults import REFERENCE_B, _evaluate, _refused

SHIPPED = ["a", "b", "c", "diagonal", "term/b"]
REFERENCE = REFERENCE_B.parent
CELL, SEED = Cell(40, 4, 8, 16), 7_000_000  # a cell of the grid and the evaluation's map seeds


def _world(name: str) -> WorldConfig:
    return WorldConfig.from_dict(checkpoint_config(REFERENCE / name / "model.zip")[0])


def test_an_unknown_path_or_onnx_off_the_cpu_is_one_line():
    check_inference("torch", "cuda")
    with pytest.raises(ValueError, match=r"^inference='fast' is not allowed: one of torch, onnx$"):
        check_inference("fast")
    with pytest.raises(ValueError, match=r"^inference=onnx runs on the CPU, not device='cuda'"):
        check_inference("onnx", "cuda")


@pytest.mark.parametrize("name", SHIPPED)
def test_onnx_logits_equal_torchs_to_rounding(name):
    policy = load_checkpoint(REFERENCE / name / "model.zip", device="cpu").policy
    space, rng = policy.observation_space, np.random.default_rng(0)
    maps = rng.random((64, *space["map"].shape), dtype=np.float32)
    vector = rng.random((64, *space["vector"].shape), dtype=np.float32)
    torch_actor, onnx_actor = Actor(policy), Actor(policy, inference="onnx")
    assert onnx_actor.inference == "onnx"
    expected, state = torch_actor.logits(maps, vector, torch_actor.initial_state(64))
    got, onnx_state = onnx_actor.logits(maps, vector, onnx_actor.initial_state(64))
    np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(onnx_state.numpy(), state.numpy(), rtol=1e-4, atol=1e-4)


class _BothPaths:
    """Acts with torch's greedy actions and counts the agent-steps where onnx's greedy action on the same state
    differs (the states are torch's own episodes')."""

    def __init__(self, torch_actor: Actor, onnx_actor: Actor, config: WorldConfig, tally: list[int]) -> None:
        self.paths = [PolicyController(a, config, deterministic=True) for a in (torch_actor, onnx_actor)]
        self.tally = tally

    def reset(self, state, mask) -> None:
        for path in self.paths:
            path.reset(state, mask)

    def act(self, state, maps, vector, active=None):
        mine, other = (path.act(state, maps, vector, active) for path in self.paths)
        rows = np.ones(state.n_worlds, bool) if active is None else np.asarray(active, bool)
        self.tally[0] += int((mine != other)[rows].sum())
        self.tally[1] += int(rows.sum()) * state.n_agents
        return mine


@pytest.mark.parametrize("name", SHIPPED)
def test_greedy_actions_of_every_shipped_policy_agree_on_its_own_episodes(name):
    world = _world(name)
    torch_actor = load_actor(REFERENCE / name / "model.zip", world)
    onnx_actor = load_actor(REFERENCE / name / "model.zip", world, inference="onnx")
    tally = [0, 0]
    run_cell(lambda config, seed: _BothPaths(torch_actor, onnx_actor, config, tally), world, CELL, 0, 4, 1, SEED)
    assert tally[1] > 1000 and tally[0] <= tally[1] // 1000, tally  # at most one agent-step in a thousand


def test_sampled_episodes_pair_on_a_small_grid():
    """Sampled episodes of B's shipped policy on the two paths, the same maps and streams: the paired difference of
    the found fractions has a 95 % CI that includes 0 and most episodes are the same episode."""
    world, path = _world("term/b"), REFERENCE / "term/b" / "model.zip"
    frames = [
        run_cell(policy_factory(load_actor(path, world, inference=path_name)), world, CELL, 0, 24, 1, SEED)
        for path_name in ("torch", "onnx")
    ]
    diff = frames[1].found_fraction.to_numpy() - frames[0].found_fraction.to_numpy()
    _, low, high = bootstrap_mean_ci(diff)
    assert low <= 0 <= high, (low, high)
    assert (frames[1].L.to_numpy() == frames[0].L.to_numpy()).mean() >= 0.75


@pytest.mark.app
def test_an_evaluation_records_its_path_and_refuses_another(tmp_path, capsys):
    out = tmp_path / "eval"
    _evaluate(out, f"checkpoint={REFERENCE_B / 'model.zip'}", "inference=onnx")
    assert OmegaConf.load(out / "evaluation.yaml").inference == "onnx"
    _refused(capsys, lambda: _evaluate(out, f"checkpoint={REFERENCE_B / 'model.zip'}"), "inference: 'onnx' there")
    _refused(capsys, lambda: _evaluate(tmp_path / "h", "inference=onnx"), "inference='onnx'", "device=cpu")
    _refused(capsys, lambda: _evaluate(tmp_path / "h", "inference=jit"), "inference='jit'", "torch, onnx")
    assert not (tmp_path / "h").exists()
