"""Evaluation throughput: a heuristic, or a policy checkpoint, on every Table 2 cell with a few maps; agent-steps/s
and the projected time of the full grid (3000 maps × 5 repeats). Smaller batches than the full run's make the
projection pessimistic."""

from __future__ import annotations

import time
from typing import TextIO

from searchrl.controllers.factory import heuristic_factory, policy_factory
from searchrl.evaluate.grid import table2_cells
from searchrl.evaluate.runner import run_cell
from searchrl.policies.checkpoint import checkpoint_config, checkpoint_label, load_actor
from searchrl.threads import use_threads
from searchrl.world.config import WorldConfig

FULL_EPISODES_PER_CELL = 100 * 5


def run(controller: str = "surfing", maps: int = 10, checkpoint: str | None = None, threads: int = 2,
        device: str = "cpu", log: TextIO | None = None) -> list[dict]:  # fmt: skip
    """One row: agent-steps/s of `controller`, or of `checkpoint`'s policy with its network on `device` (a checked
    one, searchrl/policies/device.py), over every Table 2 cell with `maps` maps of one repeat."""
    cells = table2_cells([20, 40, 80, 160], [4, 8, 16, 32], [8, 16, 32, 64], [32, 64, 128, 256])
    if checkpoint:
        use_threads(threads, network_on_cpu=str(device) == "cpu")
        world = WorldConfig.from_dict(checkpoint_config(checkpoint)[0])
        actor = load_actor(checkpoint, world, device=device)
        factory = policy_factory(actor)
        controller = f"policy:{checkpoint_label(checkpoint)}"
    else:
        name, world = controller, WorldConfig()
        factory = heuristic_factory(name, check=world)
    observed = checkpoint is not None
    run_cell(factory, world, cells[0], 0, 1, 1, 0, needs_observation=observed)  # warm-up: numba cache
    steps = [0]
    start = time.perf_counter()
    for index, cell in enumerate(cells):
        run_cell(factory, world, cell, index, maps, 1, 7_000_000, needs_observation=observed,
                 on_steps=lambda s: steps.__setitem__(0, steps[0] + s))  # fmt: skip
    elapsed = time.perf_counter() - start
    rate = steps[0] / elapsed
    projected = elapsed * FULL_EPISODES_PER_CELL / maps
    row = {"case": f"{controller}_table2_{maps}maps", "engine": "evaluate", "device": str(device),
           "agent_steps_per_s": round(rate, 1), "projected_full_grid_s": round(projected, 1)}  # fmt: skip
    if log:
        print(f"{row['case']}: {rate:,.0f} agent-steps/s over {len(cells)} cells ({elapsed:.1f} s); full grid "
              f"(3000 maps x 5 repeats) projected {projected / 60:.1f} min, limit 20 min", file=log)  # fmt: skip
    return [row]
