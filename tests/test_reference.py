"""The shipped reference policies (runs/reference/<model>/): complete, loadable, trained to their stated budget."""

from __future__ import annotations

import csv
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from searchrl.controllers.policy import PolicyController, checkpoint_config
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.runner import cell_config
from searchrl.world.config import WorldConfig
from searchrl.world.observe import observe
from searchrl.world.reset import reset_world
from searchrl.world.state import allocate

REFERENCE = Path(__file__).resolve().parents[1] / "runs" / "reference"
SHIPPED = sorted(p.parent.name for p in REFERENCE.glob("*/model.zip"))


def test_reference_folder_documents_every_shipped_policy():
    text = (REFERENCE / "README.md").read_text()
    assert all(f"runs/reference/{model}" in text for model in SHIPPED)


@pytest.mark.parametrize("model", SHIPPED)
def test_shipped_policy_is_complete_and_acts(model):
    folder = REFERENCE / model
    assert (folder / "model.zip").stat().st_size < 8 * 2**20  # a few MB
    world_dict, _, name = checkpoint_config(folder / "model.zip")
    assert name == model
    saved = OmegaConf.load(folder / "config.yaml")
    with zipfile.ZipFile(folder / "model.zip") as archive:  # SB3 stores num_timesteps in its JSON "data"
        trained = json.loads(archive.read("data"))["num_timesteps"]
    assert saved.total_timesteps <= trained < saved.total_timesteps + 8192  # stopped at the first rollout past it
    rows = list(csv.DictReader(open(folder / "progress.csv")))
    assert int(rows[-1]["time/total_timesteps"]) == trained
    config = cell_config(WorldConfig.from_dict(world_dict), Cell(40, 4, 8, 16))
    state = allocate(config, 2)
    for w in range(2):
        reset_world(config, state, w, np.random.default_rng(w))
    controller = PolicyController.load(folder / "model.zip", config, seed=0)
    controller.reset(state, np.ones(2, bool))
    actions = controller.act(state, *observe(config, state))
    assert actions.shape == (2, 4) and ((actions >= 0) & (actions < config.n_actions)).all()
