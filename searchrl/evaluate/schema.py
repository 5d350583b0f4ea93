"""Hydra schemas of the evaluation app (conf/evaluate.yaml, conf/controller/). Each controller's schema lives
beside its class (searchrl/controllers/*.py); here every entry of the registry (searchrl/controllers/registry.py)
is stored as `<name>_schema`, which conf/controller/<name>.yaml names."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from omegaconf import MISSING

from searchrl.controllers.registry import HEURISTICS
from searchrl.evaluate.runner import BATCH_MB
from searchrl.shared_schema import CONF_DIR, EnvConfig, ModelConfig, register_shared_configs, scenario_default


@dataclass
class GridConfig:
    world_sizes: list[int] = field(default_factory=lambda: [20, 40, 80, 160])  # Table 2
    n_targets: list[int] = field(default_factory=lambda: [4, 8, 16, 32])
    n_distributions: list[int] = field(default_factory=lambda: [8, 16, 32, 64])
    max_agents: list[int] = field(default_factory=lambda: [32, 64, 128, 256])  # §6.3's density limits
    agents: list[int] | None = None  # only these team sizes N (null: 1, 2, 4, … up to each size's limit)
    maps_per_cell: int = 100  # 30 cells × 100 = 3000 maps
    repeats: int = 5


@dataclass
class EvaluateConfig:
    env: EnvConfig = field(default_factory=EnvConfig)  # world settings of heuristics (+model=a|b|c|diagonal)
    model: ModelConfig | None = None
    controller: Any = MISSING
    checkpoint: str | None = None  # a trained model.zip: evaluated instead of the controller, with its own settings
    extensions: list[str] = field(default_factory=list)  # modules that register parts (searchrl/command_line.py)
    suite: Any = None  # a frozen scenario suite (conf/suite/): its cells, maps, seed and scenarios, one folder each
    # Only these of the suite's scenarios (labels or shell patterns), each into the folder the whole suite gives it
    suite_scenarios: list[str] | None = None
    deterministic: bool = False  # policies: argmax instead of sampled actions
    # What a reset draws besides the sizes and the prior (conf/scenario/); any scenario applies to a checkpoint too.
    scenario: dict[str, Any] = field(default_factory=scenario_default)
    grid: GridConfig = field(default_factory=GridConfig)
    cell: str | None = None  # one cell of the grid, e.g. n40_N2: the maps the whole grid plays there
    baseline: str | None = None  # an evaluation folder: the paired verdicts against it, printed at the end
    seed: int = 7_000_000  # evaluation map seeds: base + 100000·cell + map, disjoint from training and validation
    shard: int = 0  # this job evaluates cells shard, shard + num_shards, …
    num_shards: int = 1
    out_dir: str | None = None  # default runs/eval/<controller> or runs/eval/policy/<run path under runs/>
    batch_mb: float = BATCH_MB  # memory budget of one batch of worlds
    bound_draws: int = 1000  # placements per map for the search bound columns (searchrl/evaluate/cell_bounds.py)
    bound_cache: str | None = "runs/bounds"  # bounds computed once per map, shared by evaluations; null: no cache
    threads: int = 2
    # torch device of a checkpoint's network: cpu, cuda, cuda:<index>, mps or auto (heuristics run on the CPU).
    # Recorded: CUDA rounds the logits otherwise than the CPU, so a folder's cells all come from one kind of device.
    device: str = "cpu"
    # a checkpoint's network on the CPU: torch (the traced TorchScript path, bit for bit the golden episodes) or onnx
    # (ONNX Runtime, about 1.4x faster, rounds otherwise: searchrl/policies/onnx_extractor.py). Recorded.
    inference: str = "torch"
    progress_bar: bool = True


def register_configs() -> None:
    """The evaluation schemas in Hydra's ConfigStore, each registered heuristic's as `controller/<name>_schema`; one
    without a conf/controller/<name>.yaml (added by `registry.register`) is also the option `controller=<name>` at
    its schema's defaults. The app runs this at import; a script that registers a heuristic later runs it again."""
    cs = register_shared_configs()  # env and model groups are shared with training
    cs.store(name="evaluate_schema", node=EvaluateConfig)
    for name, entry in HEURISTICS.items():
        cs.store(group="controller", name=f"{name}_schema", node=entry.schema)
        if not (CONF_DIR / "controller" / f"{name}.yaml").is_file():
            cs.store(group="controller", name=name, node=entry.schema)
