"""Validation during training (searchrl/train/callbacks.py): a fixed set of worlds and a fixed action stream, played
by a copy of the training policy, as evaluation plays them."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import torch
from omegaconf import OmegaConf
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

from searchrl.controllers.policy import PolicyController
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.runner import cell_config, run_cell
from searchrl.policies.actor import policy_copy
from searchrl.policies.checkpoint import checkpoint_config, load_actor, load_checkpoint
from searchrl.policies.recurrent import SequenceLstmPolicy
from searchrl.train.build import make_algorithm, make_vec_env
from searchrl.train.callbacks import run_episodes
from searchrl.train.plan import Plan, make_plan
from searchrl.train.run_record import config_record
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import IidObstacles, Scenario
from tests.test_train import TINY, _compose

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

SHIPPED_B = Path(__file__).resolve().parents[1] / "runs" / "reference" / "term" / "b" / "model.zip"


def test_same_weights_give_the_same_validation_and_leave_the_training_stream_alone():
    world_dict, _, _ = checkpoint_config(SHIPPED_B)
    config = WorldConfig.from_dict({**world_dict, "world_size": 20, "n_agents": 2, "max_steps": 24})
    model = load_checkpoint(SHIPPED_B, device="cpu")
    torch.manual_seed(123)
    before = torch.get_rng_state()
    first = run_episodes(config, 3, seed=5, model=model)
    assert torch.equal(torch.get_rng_state(), before)  # training's own sampling is not shifted by a validation
    torch.manual_seed(999)  # whatever the training stream is at the next validation
    assert run_episodes(config, 3, seed=5, model=model) == first
    other = [run_episodes(config, 3, seed=s, model=model)["found_fraction"] for s in (6, 7, 8)]
    assert len({first["found_fraction"], *other}) > 1  # the seed does pick the worlds


def test_validation_reports_what_evaluation_reports_on_the_same_worlds_and_seed():
    """A validation set of seed s is the evaluation's cell 0 under seed s: on a cell's world the validation's
    metrics are the means of `run_cell`'s rows (the evaluation app's episode runner and inference path), in the
    paper's scenario and in another, with sampled and with argmax actions."""
    world = WorldConfig.from_dict(checkpoint_config(SHIPPED_B)[0])
    model = load_checkpoint(SHIPPED_B, device="cpu")
    actor = load_actor(SHIPPED_B, world)
    cell = Cell(20, 2, 4, 8)
    for scenario, deterministic in ((Scenario(), False), (Scenario(IidObstacles(0.2)), True)):
        validation = run_episodes(cell_config(world, cell), 5, 11, model, deterministic, scenario)
        frame = run_cell(lambda config, streams, d=deterministic: PolicyController(actor, config, d, streams),
                         world, cell, 0, maps=5, repeats=1, seed=11, scenario=scenario)  # fmt: skip
        columns = ("found_fraction", "L", "R", "F", "M_bar")  # run_cell's (validation also logs collisions)
        assert {name: validation[name] for name in columns} == {name: frame[name].mean() for name in columns}
        assert validation["found_fraction"] > 0


# Validation takes one path on every device; where torch sees CUDA (a GPU machine), these tests run there too.
DEVICES = ["cpu", *(["cuda"] if torch.cuda.is_available() else [])]


@pytest.fixture(scope="module", params=[(a, d) for d in DEVICES for a in ("recurrent_ppo", "a2c")], ids="-".join)
def trained(request) -> tuple[Plan, OnPolicyAlgorithm]:
    """A tiny model after one rollout and its update, left as the training loop leaves it between rollouts: in
    training mode, with SB3's last distribution (a minibatch's, with its graph) held where SB3 keeps it."""
    algo, device = request.param
    tiny = [o for o in TINY if algo != "a2c" or "batch_size" not in o]  # A2C has no minibatches
    plan = make_plan(_compose(["+model=b", f"algo={algo}", *tiny, f"device={device}"]))
    model = make_algorithm(plan, make_vec_env(plan, seed=0))
    model.learn(256)
    assert model.policy.training
    return plan, model


def test_a_trained_policy_copies_after_an_update(trained):
    """`policy_copy` (validation's copy) holds the weights on the model's device after model.learn; so does
    deepcopy of SequenceLstmPolicy, which keeps no minibatch's graph (searchrl/policies/recurrent.py). SB3's own
    ActorCriticPolicy (A2C's) still keeps one, which deepcopy refuses: validation builds its copy instead."""
    _, model = trained
    copies = [policy_copy(model)]
    if isinstance(model.policy, SequenceLstmPolicy):
        copies.append(copy.deepcopy(model.policy))
    for twin in copies:
        assert twin is not model.policy and type(twin) is type(model.policy) and twin.device == model.policy.device
        for name, value in model.policy.state_dict().items():
            assert torch.equal(twin.state_dict()[name], value), name


def _generators() -> list[torch.Tensor]:
    """The states of torch's global generators training samples from: the CPU's and each CUDA device's."""
    return [torch.get_rng_state(), *(torch.cuda.get_rng_state_all() if torch.cuda.is_available() else [])]


def test_validation_acts_with_a_copy_and_reports_what_evaluation_reports(trained, tmp_path):
    """After an update, validation leaves the training policy as it was (its mode, its weights, torch's generator),
    and its metrics are the means of the evaluation app's rows for the same weights saved as a run's checkpoint and
    loaded by evaluation's `load_actor` on the device the model trained on."""
    plan, model = trained
    policy = model.policy
    weights = {name: value.clone() for name, value in policy.state_dict().items()}
    generators = _generators()
    cell = Cell(20, 2, 4, 8)
    validation = run_episodes(cell_config(plan.world, cell), 4, 11, model)
    assert model.policy is policy and policy.training  # not put in evaluation mode by the actor
    assert all(torch.equal(value, weights[name]) for name, value in policy.state_dict().items())
    assert all(torch.equal(now, then) for now, then in zip(_generators(), generators, strict=True))
    model.save(tmp_path / "model.zip")
    OmegaConf.save(config_record(plan.settings), tmp_path / "config.yaml")  # what the checkpoint is read by
    actor = load_actor(tmp_path / "model.zip", plan.world, device=model.device)
    frame = run_cell(lambda config, streams: PolicyController(actor, config, False, streams), plan.world, cell, 0,
                     maps=4, repeats=1, seed=11)  # fmt: skip
    columns = ("found_fraction", "L", "R", "F", "M_bar")
    assert {name: validation[name] for name in columns} == {name: frame[name].mean() for name in columns}
