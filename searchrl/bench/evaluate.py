"""Evaluation throughput: a heuristic, or a policy checkpoint, on the Table 2 cells (all, or those named) with a few
maps; agent-steps/s, the projected time of the full grid (3000 maps × 5 repeats), and the work the worlds did:
`world_steps` (each step of the batch counts its K worlds) against `episode_steps` (the steps of the episodes
played, Σ L), whose ratio `busy_share` is the share of the worlds' steps that belonged to an episode. Fewer episodes
a cell than the full run's make the projection pessimistic: the cell's batch holds fewer worlds."""

from __future__ import annotations

import dataclasses
import time
from typing import TextIO

from searchrl.controllers.factory import heuristic_factory, policy_factory
from searchrl.evaluate.grid import table2_cells
from searchrl.evaluate.runner import BATCH_MB, cell_config, cell_slots, run_cell
from searchrl.evaluate.schema import GridConfig
from searchrl.policies.checkpoint import checkpoint_config, checkpoint_label, load_actor
from searchrl.threads import use_threads
from searchrl.world.config import WorldConfig

FULL_EPISODES_PER_CELL = 100 * 5
_GRID = GridConfig()  # the evaluation's own grid: the bench's cells are its cells, in its order (their map seeds)
GRID = table2_cells(_GRID.world_sizes, _GRID.n_targets, _GRID.n_distributions, _GRID.max_agents)


def run(
    controller: str = "surfing",
    maps: int = 10,
    checkpoint: str | None = None,
    threads: int = 2,
    device: str = "cpu",
    log: TextIO | None = None,
    repeats: int = 1,
    cells: str | None = None,
    settings: dict | None = None,
    inference: str = "torch",
) -> list[dict]:
    """One row: agent-steps/s of `controller`, or of `checkpoint`'s policy with its network on `device` (a checked
    one, searchrl/policies/device.py), over the Table 2 cells (`cells`, comma-separated keys: all by default) with
    `maps` maps of `repeats` repeats, as the evaluation runs them (its memory budget per batch). A heuristic takes
    `settings`, a policy runs on its `inference` path. A controller that plays worlds of its own (a planner's
    rollouts) and counts them in `work` (`agent_steps`, `seconds`, `steps`, `worlds`, `agents`) has their rate
    reported beside the engine's own on batches of the same size, random actions, in the same run (`inner_share`)."""
    keys = None if cells is None else set(cells.split(","))
    if checkpoint:
        use_threads(threads, network_on_cpu=str(device) == "cpu")
        world = WorldConfig.from_dict(checkpoint_config(checkpoint)[0])
        actor = load_actor(checkpoint, world, device=device, inference=inference)
        factory = policy_factory(actor)
        controller = f"policy:{checkpoint_label(checkpoint)}"
    else:
        name, world = controller, WorldConfig()
        factory = heuristic_factory(name, settings, check=world)
    made: list = []  # the controllers each cell made, for their own work

    def making(config: WorldConfig, seed, inner=factory):
        made.append((config, inner(config, seed)))
        return made[-1][1]

    observed = checkpoint is not None
    run_cell(factory, world, GRID[0], 0, 1, 1, 0, needs_observation=observed)  # warm-up: numba cache
    steps, world_steps, episode_steps = [0], [0], 0
    start = time.perf_counter()
    for index, cell in enumerate(GRID):
        if keys is not None and cell.key not in keys:
            continue
        slots = cell_slots(cell_config(world, cell), BATCH_MB, maps * repeats)  # the worlds run_cell steps

        def tally(agent_steps: int, slots: int = slots) -> None:  # called once a step
            steps[0] += agent_steps
            world_steps[0] += slots

        frame = run_cell(
            making, world, cell, index, maps, repeats, 7_000_000, needs_observation=observed, on_steps=tally
        )
        episode_steps += int(frame["L"].sum())
    elapsed = time.perf_counter() - start
    rate = steps[0] / elapsed
    projected = elapsed * FULL_EPISODES_PER_CELL / (maps * repeats)
    what = "table2" if keys is None else "+".join(sorted(keys))
    row = {
        "case": f"{controller}_{what}_{maps}maps_{repeats}repeats" + ("_onnx" if inference == "onnx" else ""),
        "engine": "evaluate",
        "device": str(device),
        "agent_steps_per_s": round(rate, 1),
        "seconds": round(elapsed, 1),
        "projected_full_grid_s": round(projected, 1) if keys is None else None,
        "world_steps": world_steps[0],
        "episode_steps": episode_steps,
        "busy_share": round(episode_steps / max(1, world_steps[0]), 4),
    }
    if any(isinstance(getattr(c, "work", None), dict) for _, c in made):
        row.update(inner_work(made))
    if log:
        print(
            f"{row['case']}: {rate:,.0f} agent-steps/s over {len(GRID) if keys is None else len(keys)} cells "
            f"({elapsed:.1f} s); {row['busy_share']:.0%} of the worlds' steps in an episode",
            file=log,
        )
        if keys is None:
            print(f"full grid (3000 maps x 5 repeats) projected {projected / 60:.1f} min, limit 20 min", file=log)
        if "inner_share" in row:
            print(
                f"its own worlds: {row['inner_agent_steps_per_s']:,.0f} agent-steps/s over {row['inner_seconds']:.1f} s"
                f" ({row['inner_share']:.0%} of the engine's {row['engine_agent_steps_per_s']:,.0f} on batches of "
                f"{row['inner_batch']} worlds, random actions); {row['agent_steps_per_s']:,.1f} decisions/s",
                file=log,
            )
    return [row]


def inner_work(made: list) -> dict:
    """The worlds the controllers played on their own (`work`), against the engine stepping batches of the same size
    in the same worlds with random actions: agent-steps/s each, and their ratio `inner_share` (how near the
    controller's own stepping comes to the world's speed; the rest is its rule and Python)."""
    from searchrl.bench.world import measure
    from searchrl.world.step import step

    steps = seconds = engine_seconds = 0.0
    batch = 1
    for config, controller in made:
        work = getattr(controller, "work", None)
        if not isinstance(work, dict) or not work.get("steps"):
            continue
        batch = max(1, round(work["worlds"] / work["steps"]))
        inner = dataclasses.replace(config, n_agents=int(work["agents"]))
        engine = measure(inner, batch, step, lambda c, s: None, seconds=1.0, min_steps=5)[0][0]
        steps += work["agent_steps"]
        seconds += work["seconds"]
        engine_seconds += work["agent_steps"] / engine
    if not seconds:
        return {}
    return {
        "inner_agent_steps_per_s": round(steps / seconds, 1),
        "inner_seconds": round(seconds, 1),
        "inner_batch": batch,
        "engine_agent_steps_per_s": round(steps / engine_seconds, 1),
        "inner_share": round(engine_seconds / seconds, 4),
    }
