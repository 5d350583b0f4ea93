"""Run a controller on one grid cell: `maps` maps × `repeats` repeats as batched worlds, one episode each."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pandas as pd

from searchrl.controllers.base import Controller
from searchrl.evaluate.grid import Cell, map_seed
from searchrl.world.config import WorldConfig
from searchrl.world.metrics import episode_metrics
from searchrl.world.observe import observation_buffers, observe
from searchrl.world.reset import reset_world
from searchrl.world.state import WorldState, allocate
from searchrl.world.step import step
from searchrl.world.streams import WorldStreams

# `world` names the sensing the episodes ran under (WorldConfig.sensing_label: "bayes" λk = 1, "paper" k = n).
# The evaluation app (__main__) adds the map's search bound, searchrl/evaluate/bound.py's BOUND_COLUMNS.
COLUMNS = ["controller", "model", "world", "n", "N", "targets", "map_seed", "repeat", "found_fraction", "L", "R",
           "F", "M_bar"]  # fmt: skip


def cell_config(world: WorldConfig, cell: Cell) -> WorldConfig:
    """The model's world settings on one Table 2 cell (n, targets, m fixed; N from the cell)."""
    return replace(
        world,
        world_size=(cell.n, cell.n),
        n_targets=(cell.n_targets, cell.n_targets),
        n_distributions=(cell.n_distributions, cell.n_distributions),
        n_agents=cell.n_agents,
    )


def worlds_per_batch(config: WorldConfig, budget_mb: float) -> int:
    """How many worlds of this cell fit the memory budget (beliefs dominate: N · 2 · S² · 4 bytes each)."""
    side = config.world_size[1] + 2 * config.halo
    per_world = config.n_agents * 2 * side * side * 4 + 6 * side * side * 4
    return max(1, int(budget_mb * 2**20 // per_world))


def episode_streams(seed: int, cell_index: int, episodes: list[tuple[int, int]]) -> tuple[WorldStreams, WorldStreams]:
    """(the world's, the controller's) random streams of the episodes (map, repeat): each episode's own, keyed by
    (seed, cell, map, repeat), so how a cell is split into batches, threads or shards changes no episode."""
    keys = [(seed, cell_index, m, r) for m, r in episodes]
    return WorldStreams([(*key, 0) for key in keys]), WorldStreams([(*key, 1) for key in keys])


def run_cell(
    controller_factory: Callable[[WorldConfig, WorldStreams], Controller],
    world: WorldConfig,
    cell: Cell,
    cell_index: int,
    maps: int,
    repeats: int,
    seed: int,
    budget_mb: float = 1024.0,
    needs_observation: bool = True,
    on_steps: Callable[[int], None] | None = None,
    on_done: Callable[[WorldState, np.ndarray], None] | None = None,
) -> pd.DataFrame:
    """One row per episode (COLUMNS minus controller, model and world). Every repeat of a map starts from the same world
    (map, targets and start cells come from the map seed); repeats differ in the step draws and the controller's
    own randomness, each episode's from its own streams (`episode_streams`; `controller_factory(config, streams)`
    builds a controller drawing from them), so `budget_mb` changes how many worlds step together and nothing else.
    `on_done(state, first)` sees the batch's state when the worlds in `first` (K,) bool end their episode
    (analysis/missed_targets.py reads it)."""
    config = cell_config(world, cell)
    episodes = [(m, r) for m in range(maps) for r in range(repeats)]
    batch = worlds_per_batch(config, budget_mb)
    rows = []
    for start in range(0, len(episodes), batch):
        chunk = episodes[start : start + batch]
        k = len(chunk)
        state = allocate(config, k)
        seeds = [map_seed(seed, cell_index, m) for m, _ in chunk]
        for w, s in enumerate(seeds):
            reset_world(config, state, w, np.random.default_rng(s))
        rng, controller_rng = episode_streams(seed, cell_index, chunk)
        controller = controller_factory(config, controller_rng)
        controller.reset(state, np.ones(k, bool))
        buffers = observation_buffers(config, k)
        maps_obs, vector = observe(config, state, buffers) if needs_observation else (None, None)
        finished = np.zeros(k, bool)
        final: dict[str, np.ndarray] = {}
        while not finished.all():
            result = step(config, state, controller.act(state, maps_obs, vector, active=~finished), rng)
            if needs_observation:
                maps_obs, vector = observe(config, state, buffers)
            first = result.done & ~finished
            if first.any():  # finished worlds keep stepping with the batch; only their first episode counts
                metrics = episode_metrics(state)
                for name, values in metrics.items():
                    final.setdefault(name, np.zeros(k, values.dtype))[first] = values[first]
                finished |= result.done
                if on_done:
                    on_done(state, first)
            if on_steps:
                on_steps(int((~finished | first).sum()) * config.n_agents)
        for w, (_, r) in enumerate(chunk):
            rows.append(
                {"n": cell.n, "N": cell.n_agents, "targets": cell.n_targets, "map_seed": seeds[w], "repeat": r,
                 **{name: final[name][w] for name in ("found_fraction", "L", "R", "F", "M_bar")}}
            )  # fmt: skip
    return pd.DataFrame(rows)
