"""Hydra schemas of the evaluation app (conf/evaluate.yaml, conf/controller/)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

from searchrl.train.schema import EnvConfig, ModelConfig
from searchrl.train.schema import register_configs as register_train_configs


@dataclass
class ControllerConfig:
    name: str = MISSING


@dataclass
class SurfingConfig(ControllerConfig):
    name: str = "surfing"
    # Block sides of the pooled gradients. [1, 3] stays inside the 11×11 field of view (the policy's window) and is
    # the paper's greedy local surfing; [1, 3, 9, 27] also follows the information up to 40 cells away and finds
    # less on most cells of the grid (README, "Results: baselines").
    scales: list[int] = field(default_factory=lambda: [1, 3])
    w_p: float = 0.6  # weight of probability in the information surfed
    w_u: float = 0.4  # weight of uncertainty
    repulsion: float = 0.4  # weight of the unit Coulomb push away from visible agents


@dataclass
class GreedyConfig(ControllerConfig):
    name: str = "greedy"
    # Not one of the paper's baselines: a move is scored by the information its footprint would sense over the
    # next `horizon` steps in that direction (inside the field of view), later steps weighted by `discount`.
    horizon: int = 2
    discount: float = 0.7
    w_p: float = 0.6  # the same weights as surfing's, so the two differ only in how they read the belief
    w_u: float = 0.4
    # Weight of p̂·(1 − û), the chance a target sits in the cell (§4.1.4 keeps a draw from p with probability
    # 1 − u/max u); w_p=0 w_u=0 w_t=1 scores a move by the targets its footprint expects to detect.
    w_t: float = 0.0
    # Weight of cells another agent in view reaches in fewer moves (1: no difference; < 1 splits the view).
    contested: float = 1.0
    # Cells that fewer footprint positions can sense (edges, corners, beside obstacles) count
    # (Γ_total / Γ_reach)^reach times; 0 counts every cell the same (searchrl/controllers/greedy.py).
    reach: float = 0.0
    # Lower what an agent believes under the footprints of the neighbours it sees, as their sensing would (for
    # worlds without merging, model C; searchrl/controllers/greedy.py).
    seen: bool = False
    # Count what an agent believes of a cell exp(−age · ρ · steps since it last saw the cell's truth) times, ρ the
    # rate at which a team spread evenly senses a cell (for worlds without merging; searchrl/controllers/greedy.py).
    age: float = 0.0


@dataclass
class CoverageConfig(ControllerConfig):
    name: str = "coverage"
    radius: int = 1  # lanes 2·radius + 1 rows apart


@dataclass
class RandomConfig(ControllerConfig):
    name: str = "random"


@dataclass
class GridConfig:
    world_sizes: list[int] = field(default_factory=lambda: [20, 40, 80, 160])  # Table 2
    n_targets: list[int] = field(default_factory=lambda: [4, 8, 16, 32])
    n_distributions: list[int] = field(default_factory=lambda: [8, 16, 32, 64])
    max_agents: list[int] = field(default_factory=lambda: [32, 64, 128, 256])  # §6.3's density limits
    maps_per_cell: int = 100  # 30 cells × 100 = 3000 maps
    repeats: int = 5


@dataclass
class EvaluateConfig:
    env: EnvConfig = field(default_factory=EnvConfig)  # world settings of heuristics (+model=a|b|c|diagonal)
    model: ModelConfig | None = None
    controller: Any = MISSING
    checkpoint: str | None = None  # a trained model.zip: evaluated instead of the controller, with its own settings
    deterministic: bool = False  # policies: argmax instead of sampled actions
    grid: GridConfig = field(default_factory=GridConfig)
    seed: int = 7_000_000  # evaluation map seeds: base + 100000·cell + map, disjoint from training and validation
    shard: int = 0  # this job evaluates cells shard, shard + num_shards, …
    num_shards: int = 1
    out_dir: str | None = None  # default runs/eval/<controller or checkpoint run>
    batch_mb: float = 1024.0  # memory budget of one batch of worlds
    threads: int = 2
    progress_bar: bool = True


def register_configs() -> None:
    register_train_configs()  # env and model groups are shared with training
    cs = ConfigStore.instance()
    cs.store(name="evaluate_schema", node=EvaluateConfig)
    cs.store(group="controller", name="surfing_schema", node=SurfingConfig)
    cs.store(group="controller", name="greedy_schema", node=GreedyConfig)
    cs.store(group="controller", name="coverage_schema", node=CoverageConfig)
    cs.store(group="controller", name="random_schema", node=RandomConfig)
