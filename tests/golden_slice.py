"""Recorded outputs that every refactor must reproduce bit for bit: each shipped policy and every registered
heuristic on a small slice of the grid, through `run_cell` (the evaluation's episode loop), and the wall-aware
rules, B's teacher and the policy among walls under iid walls. The open-grid episodes of the first five
heuristics and the policies were recorded at 05d7673, before scenarios, the episode runner and the removal of the
negative experiments; columns, heuristics and the walled rows added since were written in later (each by the
commit that added it).

`python -m tests.golden_slice --write` rewrites tests/golden/slice.parquet; do that only for a change that is meant
to change episodes, and say which in the commit that does. tests/test_golden.py compares a fresh run with the file.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from searchrl.controllers.factory import heuristic_factory, policy_factory
from searchrl.controllers.registry import HEURISTICS, make_controller
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.runner import run_cell
from searchrl.policies.checkpoint import checkpoint_config, load_actor
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import PAPER, Scenario

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "golden" / "slice.parquet"
REFERENCE = ROOT / "runs" / "reference"
# Two cells of Table 2 (n=20 with 8 targets and 16 Gaussians; N=1 and N=4), two maps each, one repeat.
CELLS = [(0, Cell(20, 1, 8, 16)), (2, Cell(20, 4, 8, 16))]
MAPS, REPEATS, SEED = 2, 1, 7_000_000
WALLS = Scenario.from_dict({"obstacles": {"kind": "iid", "density": 0.2, "connected": True}})
WALLED = ("path_greedy", "sweep", "greedy_target")  # and the policy trained among walls
# Settings other than the defaults: the rollout planner imagines 3 steps instead of to the episode's end (seconds,
# not minutes, and every part of its plan still runs)
SETTINGS = {"rollout": {"horizon": 3}}


def shipped_policies() -> list[str]:
    """Every runs/reference/**/model.zip, as its folder relative to runs/reference."""
    return sorted(str(p.parent.relative_to(REFERENCE)) for p in REFERENCE.glob("**/model.zip"))


def _rows(label: str, factory, world: WorldConfig, needs_observation: bool, scenario: Scenario = PAPER
          ) -> list[pd.DataFrame]:  # fmt: skip
    frames = []
    for index, cell in CELLS:
        frame = run_cell(factory, world, cell, index, MAPS, REPEATS, SEED, needs_observation=needs_observation,
                         scenario=scenario)  # fmt: skip
        frame.insert(0, "controller", label)
        frames.append(frame)
    return frames


def golden_frame() -> pd.DataFrame:
    """One row per (controller, cell, map, repeat): the run_cell columns with the controller's name."""
    frames = []
    world = WorldConfig()  # the Bayesian world of conf/world/bayes.yaml, model B's agent model
    for name in HEURISTICS:  # every registered one
        frames += _rows(name, heuristic_factory(name, SETTINGS.get(name)), world, False)
    for name in WALLED:
        frames += _rows(f"{name}@{WALLS.label}", heuristic_factory(name), world, False, WALLS)
    # Model C's teacher: target-greedy remembering what it saw its neighbours sense (its world ages beliefs).
    saved = OmegaConf.load(REFERENCE / "c" / "config.yaml")
    world_c = WorldConfig.from_dict(OmegaConf.to_container(saved.env.world))
    teacher = OmegaConf.to_container(saved.imitation.teacher_args)
    frames += _rows("teacher:c", lambda config, seed: make_controller("greedy", config, seed, teacher), world_c, False)
    for folder in shipped_policies():
        path = REFERENCE / folder / "model.zip"
        world = WorldConfig.from_dict(checkpoint_config(path)[0])
        actor = load_actor(path, world)
        # Argmax actions, but for B's clone: a sampled action turns on the last bits of the logits, which another
        # CPU's convolution kernels may round otherwise; argmax does not, and one sampled policy keeps that path.
        deterministic = folder != "b"
        frames += _rows(f"policy:{folder}", policy_factory(actor, deterministic), world, True)
        if folder == "walls/b":
            frames += _rows(f"policy:{folder}@{WALLS.label}", policy_factory(actor, deterministic), world, True, WALLS)
    return pd.concat(frames, ignore_index=True)


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: python -m tests.golden_slice --write")
    import torch

    torch.set_num_threads(1)
    GOLDEN.parent.mkdir(exist_ok=True)
    frame = golden_frame()
    frame.to_parquet(GOLDEN)
    print(f"wrote {len(frame)} rows to {GOLDEN}")
