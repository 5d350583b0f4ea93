"""Validation during training (searchrl/train/validation.py): a fixed set of worlds and a fixed action stream."""

from __future__ import annotations

from pathlib import Path

import torch

from searchrl.controllers.policy import PolicyController
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.runner import cell_config, run_cell
from searchrl.policies.checkpoint import checkpoint_config, load_actor, load_checkpoint
from searchrl.train.validation import run_episodes
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import IidObstacles, Scenario

SHIPPED_B = Path(__file__).resolve().parents[1] / "runs" / "reference" / "term" / "b" / "model.zip"


def test_same_weights_give_the_same_validation_and_leave_the_training_stream_alone():
    world_dict, _, _ = checkpoint_config(SHIPPED_B)
    config = WorldConfig.from_dict({**world_dict, "world_size": 20, "n_agents": 2, "max_steps": 24})
    model = load_checkpoint(SHIPPED_B, "recurrent_ppo", device="cpu")
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
    model = load_checkpoint(SHIPPED_B, "recurrent_ppo", device="cpu")
    actor = load_actor(SHIPPED_B, world)
    cell = Cell(20, 2, 4, 8)
    for scenario, deterministic in ((Scenario(), False), (Scenario(IidObstacles(0.2)), True)):
        validation = run_episodes(cell_config(world, cell), 5, 11, model, deterministic, scenario)
        frame = run_cell(lambda config, streams, d=deterministic: PolicyController(actor, config, d, streams),
                         world, cell, 0, maps=5, repeats=1, seed=11, scenario=scenario)  # fmt: skip
        columns = ("found_fraction", "L", "R", "F", "M_bar")  # run_cell's (validation also logs collisions)
        assert {name: validation[name] for name in columns} == {name: frame[name].mean() for name in columns}
        assert validation["found_fraction"] > 0
