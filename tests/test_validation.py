"""Validation during training (searchrl/train/validation.py): a fixed set of worlds and a fixed action stream."""

from __future__ import annotations

from pathlib import Path

import torch
from sb3_contrib import RecurrentPPO

from searchrl.controllers.policy import checkpoint_config
from searchrl.train.validation import run_episodes
from searchrl.world.config import WorldConfig

SHIPPED_B = Path(__file__).resolve().parents[1] / "runs" / "reference" / "term" / "b" / "model.zip"


def test_same_weights_give_the_same_validation_and_leave_the_training_stream_alone():
    world_dict, _, _ = checkpoint_config(SHIPPED_B)
    config = WorldConfig.from_dict({**world_dict, "world_size": 20, "n_agents": 2, "max_steps": 24})
    model = RecurrentPPO.load(SHIPPED_B, device="cpu")
    torch.manual_seed(123)
    before = torch.get_rng_state()
    first = run_episodes(config, 3, seed=5, model=model)
    assert torch.equal(torch.get_rng_state(), before)  # training's own sampling is not shifted by a validation
    torch.manual_seed(999)  # whatever the training stream is at the next validation
    assert run_episodes(config, 3, seed=5, model=model) == first
    other = [run_episodes(config, 3, seed=s, model=model)["found_fraction"] for s in (6, 7, 8)]
    assert len({first["found_fraction"], *other}) > 1  # the seed does pick the worlds
