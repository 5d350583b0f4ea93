"""The evaluation's checks before any work: every grid cell and override against the scenario, the baseline a
scenario names, and the output folder (given, writable, not a file)."""

from __future__ import annotations

import math
from dataclasses import asdict
from pathlib import Path

from searchrl.atomic import check_own_files, check_writable
from searchrl.evaluate.comparable import identity_of, world_differences, world_identity
from searchrl.evaluate.grid import Cell, table2_cells
from searchrl.evaluate.results import coverage
from searchrl.evaluate.schema import EvaluateConfig
from searchrl.multirun import refuse
from searchrl.policies.actor import INFERENCE
from searchrl.policies.device import check_device
from searchrl.shared_schema import check_threads, override_keys
from searchrl.world.config import ConfigError, need
from searchrl.world.scenario import Scenario

# Set per cell by the grid, or training-only: a heuristic's evaluation refuses them rather than drop them.
SET_BY_GRID = (
    "env.n_worlds",
    "env.world.n_agents",
    "env.world.world_size",
    "env.world.n_targets",
    "env.world.n_distributions",
    "env.replicas",
    "deterministic",
)
LOCKS = ".locks"  # <out_dir>/.locks/: the folder's record lock and one lock per cell being run


fail = refuse  # the one-line refusal, exit status 2 (searchrl/multirun.py)

# With checkpoint=, the world, model and controller come from the checkpoint's run: these overrides cannot apply.
FIXED_BY_CHECKPOINT = ("env", "world", "model", "controller")


def check_evaluation(cfg: EvaluateConfig, overrides: list[str]) -> tuple[list[tuple[int, Cell]], Path | None, Scenario]:
    """Every check of an evaluation's settings, before any work or file: ((grid index, cell) pairs, output folder,
    scenario). Raises ConfigError naming the bad value and what is allowed."""
    if cfg.checkpoint is not None:
        fixed = [
            o
            for o, k in zip(overrides, override_keys(overrides), strict=True)
            if k.split(".")[0] in FIXED_BY_CHECKPOINT
        ]
        if fixed:
            raise ConfigError(
                f"{', '.join(fixed)} cannot apply with checkpoint={cfg.checkpoint!r}: a checkpoint is evaluated in "
                "the world, model and action set of its run (its config.yaml); remove them"
            )
    need(cfg.suite_scenarios is None, "suite_scenarios", cfg.suite_scenarios, "null without suite=<name>")
    keys = override_keys(overrides)
    if cfg.checkpoint is None:
        set_by_grid = [k for k in keys if k in SET_BY_GRID or k.startswith("env.extra_teams")]
        if set_by_grid:
            raise ConfigError(
                f"{', '.join(set_by_grid)} cannot apply to an evaluation: the grid sets N, n, targets and Gaussians "
                "per cell (grid.*), one team per world, and deterministic is for checkpoints; remove them"
            )
        for key, value in asdict(cfg.controller).items():
            if isinstance(value, float):
                need(math.isfinite(value), f"controller.{key}", value, "a finite number")
    check_device(cfg.device)  # asked for and missing: refused, never run on the CPU instead
    need(
        cfg.checkpoint is not None or cfg.device in ("cpu", "auto"),
        "device",
        cfg.device,
        f"cpu: controller={cfg.controller.name} runs on the CPU (device is for checkpoint=<model.zip>)",
    )
    need(cfg.inference in INFERENCE, "inference", cfg.inference, f"one of {', '.join(INFERENCE)}")
    need(
        cfg.inference == "torch" or (cfg.checkpoint is not None and cfg.device == "cpu"),
        "inference",
        cfg.inference,
        "torch: onnx runs a checkpoint's network on the CPU (device=cpu)",
    )
    need(0 <= cfg.seed <= 2**62, "seed", cfg.seed, "0 <= seed <= 2**62 (map seeds are seed + 100000·cell + map)")
    check_threads(cfg.threads)
    need(math.isfinite(cfg.batch_mb) and cfg.batch_mb > 0, "batch_mb", cfg.batch_mb, "a number of MiB > 0")
    need(cfg.bound_draws >= 100, "bound_draws", cfg.bound_draws, "an integer >= 100 (placements per map)")
    need(cfg.num_shards >= 1, "num_shards", cfg.num_shards, "an integer >= 1")
    need(0 <= cfg.shard < cfg.num_shards, "shard", cfg.shard, f"0 <= shard < num_shards={cfg.num_shards}")
    for name in ("maps_per_cell", "repeats"):
        need(getattr(cfg.grid, name) >= 1, f"grid.{name}", getattr(cfg.grid, name), "must be >= 1")
    scenario = Scenario.from_dict(cfg.scenario)  # ConfigError naming a bad part
    grid = cfg.grid
    cells = table2_cells(grid.world_sizes, grid.n_targets, grid.n_distributions, grid.max_agents)
    # A subset of team sizes keeps each cell's index in the whole grid, so its maps are the grid's (map_seed)
    agents = grid.agents
    on_grid = sorted({c.n_agents for c in cells})
    need(
        agents is None or (len(agents) > 0 and set(agents) <= set(on_grid)),
        "grid.agents",
        agents,
        f"null (every N) or team sizes of the grid, from {on_grid}",
    )
    indexed = [(i, c) for i, c in enumerate(cells) if agents is None or c.n_agents in agents]
    if cfg.cell is not None:  # one cell, at its index in the whole grid: the grid's maps of that cell
        keys = [c.key for _, c in indexed]
        need(cfg.cell in keys, "cell", cfg.cell, f"a cell of the grid: one of {', '.join(keys)}")
        indexed = [(i, c) for i, c in indexed if c.key == cfg.cell]
    check_baseline(cfg, scenario)
    return indexed, given_out_dir(cfg, "runs/eval/<controller or policy>"), scenario


def check_baseline(cfg: EvaluateConfig, scenario: Scenario) -> None:
    """`baseline=` names an evaluation folder of this evaluation's worlds (searchrl/evaluate/comparable.py: its
    seed, scenario, grid and, for a heuristic, the world's map and sensing settings); ConfigError naming the
    difference."""
    if cfg.baseline is None:
        return
    need(
        bool(coverage(cfg.baseline)),
        "baseline",
        cfg.baseline,
        "an evaluation folder (one with evaluation.yaml and cells/)",
    )
    ours: dict = {"seed": cfg.seed, "grid": asdict(cfg.grid), "scenario": scenario.to_dict()}
    if cfg.checkpoint is None:  # a policy's world is its run's, read once the policy loads
        ours["world"] = asdict(cfg.env.world)
    differ = world_differences(world_identity(cfg.baseline), identity_of(ours))
    need(
        not differ,
        "baseline",
        cfg.baseline,
        "a folder of this evaluation's worlds, whose map seeds name the same maps; it differs in "
        + "; ".join(f"{key}: {theirs!r} there, {mine!r} here" for key, theirs, mine in differ),
    )


def given_out_dir(cfg: EvaluateConfig, default: str) -> Path | None:
    """`out_dir=` as a folder, None when left out (the app's `default`); an empty one is refused, not taken for it."""
    need(
        cfg.out_dir is None or cfg.out_dir.strip() != "",
        "out_dir",
        cfg.out_dir,
        f"a folder (leave it out for {default})",
    )
    return None if cfg.out_dir is None else Path(cfg.out_dir)


def check_out_dir(out_dir: Path) -> None:
    """ConfigError unless the evaluation can write its folder, cells and locks there."""
    try:
        check_own_files(out_dir, "out_dir")
        check_writable(out_dir, "out_dir", folder=True)
        for part in ("cells", LOCKS):
            check_writable(out_dir / part, f"out_dir/{part}", folder=True)
        out_dir.mkdir(parents=True, exist_ok=True)  # /proc, /sys, a full disk: refused here, in one line
    except OSError as err:
        raise ConfigError(
            f"out_dir={str(out_dir)!r} is not allowed: its folders cannot be made there "
            f"({err.strerror or type(err).__name__})"
        ) from None
