"""The evaluation behind `python -m searchrl.evaluate` (searchrl/evaluate/__main__.py): `plan_evaluation` checks
every setting, `claim_evaluation` claims the folder, `run_evaluation` runs the cells; `evaluate` does all three.

Runs a controller on the Table 2/3 grid and writes one parquet file per cell, `<out_dir>/cells/<cell>.parquet`
(one row per episode), atomically; cells already written are skipped, so a rerun resumes and `shard=` /
`num_shards=` split the grid across multirun jobs. `<out_dir>/evaluation.yaml` records the settings the cells were
run with; a run with other settings into the same folder stops before any work (`searchrl/evaluate/record.py`).
Every setting and every grid cell is checked before the folder is claimed; a job runs a cell only while it holds
that cell's lock (`<out_dir>/.locks/`), so jobs sharing a folder never write one cell twice (docs/files.md).
Each row carries its map's search bound (`bound`, `bound_stderr`, `bound_fraction`; searchrl/evaluate/cell_bounds.py).
Load the results with `searchrl.evaluate.results.load`.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from omegaconf import DictConfig, OmegaConf
from tqdm import tqdm

from searchrl.atomic import FolderBusy, check_writable, hold, remove_temporaries, storage_message, write_atomic
from searchrl.command_line import import_modules
from searchrl.controllers.factory import heuristic_factory, policy_factory
from searchrl.controllers.registry import heuristic
from searchrl.evaluate.cell_bounds import BOUND_COLUMNS, cell_bounds, map_prior
from searchrl.evaluate.checks import LOCKS, check_evaluation, check_out_dir
from searchrl.evaluate.grid import Cell, map_seed
from searchrl.evaluate.record import CELL_SETTINGS, claim_folder, evaluation_settings, option_defaults
from searchrl.evaluate.results import cell_table, paired_table
from searchrl.evaluate.runner import cell_config, run_cell
from searchrl.evaluate.schema import EvaluateConfig, register_configs
from searchrl.multirun import Stopped, refuse, said_as_refusal
from searchrl.policies.checkpoint import checkpoint_config, checkpoint_label, load_actor, training_scenario
from searchrl.policies.device import resolve_device
from searchrl.shared_schema import check_known_keys, check_world_node
from searchrl.threads import use_threads
from searchrl.world.config import WorldConfig, in_context
from searchrl.world.obstacles import IidObstacles
from searchrl.world.scenario import Scenario, ScenarioMix

register_configs()


fail = refuse  # the one-line refusal, exit status 2 (searchrl/multirun.py)


def make_controller_factory(cfg: EvaluateConfig) -> tuple[WorldConfig, str, str, object, bool]:
    """(world settings, controller label, model name, factory(config, seed) -> controller, needs observations); the
    seed is an int or the episodes' WorldStreams (searchrl/evaluate/runner.py). The label
    is what results are recorded under: `policy:<run>`, or the registry's label of `controller=<name>` (greedy for
    greedy_target)."""
    if cfg.checkpoint is not None:
        world_dict, _, model_name = checkpoint_config(cfg.checkpoint)
        world = WorldConfig.from_dict(world_dict)
        run_name = checkpoint_label(cfg.checkpoint)
        device = resolve_device(cfg.device)  # checked here too: analysis scripts call this function alone
        # The thread counts before torch's first work (tracing the actor): a pool started on every core and cut to
        # fewer afterwards ran the network 2.5 times slower beside a busy core (searchrl/threads.py)
        use_threads(cfg.threads, network_on_cpu=device.type == "cpu")
        actor = load_actor(cfg.checkpoint, world, device=device, inference=cfg.inference)  # serves every cell

        return world, f"policy:{run_name}", model_name, policy_factory(actor, cfg.deterministic), True
    world = WorldConfig.from_dict(asdict(cfg.env.world))
    model_name = cfg.model.name if cfg.model is not None else "b"
    settings = asdict(cfg.controller)
    name = settings.pop("name")
    entry = heuristic(name, other="checkpoint=<model.zip>")
    return world, entry.label, model_name, heuristic_factory(name, settings, check=world), False


@dataclass
class Evaluation:
    """One evaluation folder's checked plan: its settings as typed objects (EvaluateConfig, searchrl/evaluate/
    schema.py: no DictConfig below the plan), cells (grid index, cell), folder, scenario and controller."""

    settings: EvaluateConfig
    cells: list[tuple[int, Cell]]
    out_dir: Path
    scenario: Scenario
    world: WorldConfig
    controller: str
    model: str
    factory: object
    needs_observation: bool
    shard_offset: int = 0  # a suite's folders rotate which shard runs their first cell
    record: dict | None = None  # what its claimed folder records, and so each cell it writes


@said_as_refusal
def plan_evaluation(cfg: DictConfig, overrides: list[str], default_dir: Path | None = None) -> Evaluation:
    """Every check of an evaluation, before any work or file (ConfigError naming the bad value)."""
    import_modules(cfg.get("extensions") or [])  # their parts, in a launcher's job process too
    check_known_keys(cfg)  # `+grid.map_per_cell=50` composes: refused here, not run without
    cfg = OmegaConf.to_object(cfg)  # typed from here on: the schema checked every value's type
    check_world_node(cfg.env)
    cells, out_dir, scenario = check_evaluation(cfg, overrides)
    world, controller_name, model_name, factory, needs_obs = make_controller_factory(cfg)
    for index, cell in cells:  # a cell impossible for its n or N fails now, not when reached
        with in_context(f"grid cell {index} (n={cell.n}, N={cell.n_agents})"):
            scenario.check(cell_config(world, cell))  # first: each value's type and range
            factory(cell_config(world, cell))
            walls = draws_walls(scenario)
            for m in range(cfg.grid.maps_per_cell if walls else 0):  # exact: every map its episodes will draw
                map_prior(cell_config(world, cell), map_seed(cfg.seed, index, m), scenario)
    if cfg.checkpoint is not None:  # a policy met outside its training distribution: said beside its results
        trained = Scenario.from_dict(training_scenario(cfg.checkpoint)).label
        if trained != scenario.label:
            print(
                f"note: {checkpoint_label(cfg.checkpoint)} was trained under scenario {trained} (its run's "
                f"config.yaml) and is evaluated under {scenario.label}",
                file=sys.stderr,
            )
    # Default runs/eval/<controller=…> (greedy_target's folder though its rows say greedy) or
    # runs/eval/policy/<label>: the label is the run's path under runs/, so two runs never share a folder
    default = controller_name.replace(":", "/") if cfg.checkpoint is not None else cfg.controller.name
    out_dir = out_dir or default_dir or Path(f"runs/eval/{default}")
    return Evaluation(cfg, cells, out_dir, scenario, world, controller_name, model_name, factory, needs_obs)


def draws_walls(scenario: Scenario | ScenarioMix) -> bool:
    """Whether some world of `scenario` draws obstacles, which are redrawn until agents and targets fit and may
    never fit: the evaluation then draws every map before its first cell."""
    members = getattr(scenario, "scenarios", (scenario,))
    return any(not (isinstance(s.obstacles, IidObstacles) and s.obstacles.density <= 0) for s in members)


def claim_evaluation(plan: Evaluation) -> None:
    """Make the folder and record its settings (or find them equal); ConfigError / FolderBusy / OSError."""
    check_out_dir(plan.out_dir)
    if plan.settings.bound_cache is not None:  # the bounds are written after a cell's episodes: refused now, not then
        check_writable(plan.settings.bound_cache, "bound_cache", folder=True)
    with hold(plan.out_dir / LOCKS / "evaluation.lock", f"out_dir={str(plan.out_dir)!r}", wait_s=60):
        plan.record = claim_folder(
            plan.out_dir,
            evaluation_settings(plan.settings, plan.controller, plan.model),
            option_defaults(plan.settings),
        )


def evaluate(cfg: DictConfig, overrides: list[str] | None = None) -> Path:
    """Evaluate every cell of this shard that has no result yet; returns the output directory. `overrides` are the
    command line's (Hydra's task overrides), to refuse those a checkpoint cannot apply."""
    plan = None
    try:
        plan = plan_evaluation(cfg, overrides or [])
        claim_evaluation(plan)
    except OSError as err:  # writing the folder's record: a full disk, a read-only file system
        fail(storage_message(err) or f"out_dir={str(plan.out_dir if plan else cfg.out_dir)!r}: {err}")
    return run_evaluation(plan)


def run_evaluation(plan: Evaluation) -> Path:
    """Run the plan's cells of this shard that have no result yet (its folder claimed); returns the folder."""
    cfg, out_dir, scenario, world = plan.settings, plan.out_dir, plan.scenario, plan.world
    on_cpu = cfg.checkpoint is not None and resolve_device(cfg.device).type == "cpu"
    use_threads(cfg.threads, network_on_cpu=on_cpu)  # a heuristic's or a GPU policy's world: every thread
    mine = [(i, c) for i, c in plan.cells if (i + plan.shard_offset) % cfg.num_shards == cfg.shard]
    todo = [(i, c) for i, c in mine if not (out_dir / "cells" / f"{c.key}.parquet").exists()]
    maps, repeats = cfg.grid.maps_per_cell, cfg.grid.repeats
    total = sum(maps * repeats * world.max_steps * c.n_agents for _, c in todo)
    print(f"{plan.controller}: {len(todo)} of {len(mine)} cells to run into {out_dir}", file=sys.stderr)
    start, done_steps = time.perf_counter(), 0
    try:  # a full disk mid-grid: the cells written stand, a rerun writes the rest
        with tqdm(total=total, unit="agent-step", unit_scale=True, disable=not cfg.progress_bar) as bar:
            for index, cell in todo:
                target = out_dir / "cells" / f"{cell.key}.parquet"
                try:  # one writer per cell: a job running the same folder elsewhere keeps the cells it has started
                    with hold(out_dir / LOCKS / f"{cell.key}.lock", f"cell {cell.key} of {out_dir}"):
                        if target.exists():  # finished by another job since the list was made
                            continue
                        remove_temporaries(target.parent, target.name)  # left by a killed writer of this cell
                        frame = run_cell(
                            plan.factory,
                            world,
                            cell,
                            index,
                            maps,
                            repeats,
                            cfg.seed,
                            cfg.batch_mb,
                            plan.needs_observation,
                            on_steps=bar.update,
                            scenario=scenario,
                        )
                        seeds = frame["map_seed"].unique().tolist()
                        bounds = cell_bounds(
                            world, cell, seeds, cfg.bound_draws, cfg.bound_cache, scenario=scenario, workers=cfg.threads
                        )
                        frame = frame.merge(bounds[["map_seed", *BOUND_COLUMNS]], on="map_seed", validate="many_to_one")
                        for position, (name, value) in enumerate(scenario_columns(scenario, world).items()):
                            frame.insert(position, name, value)
                        frame.insert(0, "world", world.sensing_label)
                        frame.insert(0, "model", plan.model)
                        frame.insert(0, "controller", plan.controller)
                        frame.attrs[CELL_SETTINGS] = plan.record  # the cell says what it holds (record.py)
                        write_atomic(target, lambda tmp, f=frame: f.to_parquet(tmp))
                except FolderBusy as busy:
                    print(f"skipped: {busy}", file=sys.stderr)
                    continue
                done_steps += int(((frame["L"]) * cell.n_agents).sum())
    except OSError as err:
        message = storage_message(err)
        if message is None:
            raise
        fail(f"{message}; the cells already written stay, and a rerun into {out_dir} does the rest")
    except KeyboardInterrupt:  # Ctrl-C: the cell under way is dropped whole (nothing of it was written)
        print(f"interrupted: the cells already written stay, and a rerun into {out_dir} does the rest", file=sys.stderr)
        raise Stopped(130) from None
    elapsed = time.perf_counter() - start
    if todo:
        print(
            f"done in {elapsed:.1f} s; {done_steps / max(elapsed, 1e-9):,.0f} agent-steps/s "
            f"(steps up to each episode's end)",
            file=sys.stderr,
        )
    print(cell_table(out_dir))  # what the folder holds: a number and its CI per cell
    if cfg.baseline is not None:
        print(paired_table(out_dir, cfg.baseline))
    return out_dir


def scenario_columns(scenario: Scenario, world: WorldConfig) -> dict[str, object]:
    """What a row records of its scenario: its label, its family of prior error ("paper" when the prior is right),
    the family's severity, and the prior's sharpness (the variance scale of p's Gaussians, searchrl/world/prior.py)."""
    prior = getattr(scenario, "prior", None)  # a mix has none: its rows' scale is NaN
    scale = world.prob_variance_scale if prior is None or prior.variance_scale is None else prior.variance_scale
    return {
        "scenario": scenario.label,
        "family": scenario.family,
        "severity": scenario.severity,
        "variance_scale": float("nan") if prior is None else float(scale),
    }
