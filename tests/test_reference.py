"""The shipped reference policies (runs/reference/<model>/): complete, loadable, trained to their stated budget."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from searchrl.controllers.policy import PolicyController
from searchrl.controllers.registry import make_teacher, teacher_settings
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.results import load
from searchrl.evaluate.runner import cell_config
from searchrl.policies.checkpoint import checkpoint_config
from searchrl.world.config import WorldConfig
from searchrl.world.observe import observe
from searchrl.world.reset import reset_world
from searchrl.world.state import allocate

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

REFERENCE = Path(__file__).resolve().parents[1] / "runs" / "reference"
# Every shipped policy: the four clones of target-greedy, the RL policies the README recommends (`term/<model>`,
# `walls/*`, `robust/b`), the paper's RL recipe (`rl/<model>`) and the ablations (`ablations/<model>_<change>`).
SHIPPED = sorted(str(p.parent.relative_to(REFERENCE)) for p in REFERENCE.rglob("model.zip"))


def test_reference_folder_documents_every_shipped_policy():
    text = (REFERENCE / "README.md").read_text()
    assert all(f"runs/reference/{model}" in text for model in SHIPPED)


@pytest.mark.parametrize("model", SHIPPED)
def test_shipped_policy_is_complete_and_acts(model):
    folder = REFERENCE / model
    assert (folder / "model.zip").stat().st_size < 8 * 2**20  # a few MB
    world_dict, _, name = checkpoint_config(folder / "model.zip")
    assert name in Path(model).name.split("_")  # ablations/b_tau0 and walls/term_b are models B
    saved = OmegaConf.load(folder / "config.yaml")
    with zipfile.ZipFile(folder / "model.zip") as archive:  # SB3 stores num_timesteps in its JSON "data"
        trained = json.loads(archive.read("data"))["num_timesteps"]
    assert saved.total_timesteps <= trained < saved.total_timesteps + 8192  # stopped at the first rollout past it
    if saved.total_timesteps == 0:  # a clone without RL: its record is the imitation log
        rows = list(csv.DictReader(open(folder / "imitation.csv")))
        assert saved.imitation.teacher and float(rows[-1]["accuracy"]) > 0.9
        # The recorded teacher rebuilds; that its recipe (conf/experiment) composes to this config is
        # tests/test_experiments.py's job.
        args = OmegaConf.to_container(saved.imitation.teacher_args) if "teacher_args" in saved.imitation else {}
        make_teacher(teacher_settings(saved.imitation.teacher, args), WorldConfig.from_dict(world_dict), 0)
    else:
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


@pytest.mark.skipif("b" not in SHIPPED, reason="reference B not shipped")
def test_the_readme_evaluation_command_runs_on_reference_b(tmp_path):
    """`python -m searchrl.evaluate checkpoint=runs/reference/b/model.zip`, on a two-cell slice of the grid."""
    slice_ = ["grid.world_sizes=[20]", "grid.n_targets=[4]", "grid.n_distributions=[8]", "grid.max_agents=[2]",
              "grid.maps_per_cell=2", "grid.repeats=1", "threads=1", "progress_bar=false"]  # fmt: skip
    cmd = [sys.executable, "-m", "searchrl.evaluate", "checkpoint=runs/reference/b/model.zip", *slice_,
           f"out_dir={tmp_path}", f"hydra.run.dir={tmp_path}/hydra"]  # fmt: skip
    out = subprocess.run(cmd, cwd=REFERENCE.parents[1], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    frame = load(tmp_path)
    assert len(frame) == 4 and set(frame.controller) == {"policy:reference/b"} and set(frame.model) == {"b"}
