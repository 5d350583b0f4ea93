"""Run a controller on one grid cell: `maps` maps × `repeats` repeats, one episode each, in batched worlds."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pandas as pd

from searchrl.controllers.episodes import ControllerFactory, play_episodes
from searchrl.evaluate.grid import Cell, map_seed
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.scenario import PAPER, Scenario
from searchrl.world.state import WorldState

# `world` names the sensing the episodes ran under (WorldConfig.sensing_label: "bayes" λk = 1, "paper" k = n),
# `scenario` what their resets drew (Scenario.label: "paper", "iid0.2c", "var1+off_prior1", …), `family` its
# family of prior error ("paper" when the prior is right), `severity` that family's, `variance_scale` the prior's
# sharpness (the variance scale of p's Gaussians: the world's 10 unless the scenario sets it). The evaluation app
# (__main__) adds the map's search bound, searchrl/evaluate/cell_bounds.py's BOUND_COLUMNS.
# `prior_quality` is how well the prior the agents start from points at the episode's targets (MapScore-like: 0 no
# better than uniform, 1 every target on the prior's best cell; searchrl/world/truth.py). `blocked` is the share of
# the team's moves that a wall or another agent stopped (the world's collisions per agent-step of the episode),
# `stale` the share of its agent-steps whose footprint swept no free cell new to the team (searchrl/world/swept.py).
COLUMNS = [
    "controller",
    "model",
    "world",
    "scenario",
    "family",
    "severity",
    "variance_scale",
    "n",
    "N",
    "targets",
    "map_seed",
    "repeat",
    "found_fraction",
    "L",
    "R",
    "F",
    "M_bar",
    "prior_quality",
    "blocked",
    "stale",
]


BATCH_MB = 1024.0  # run_cell's memory budget of one batch of worlds, the evaluation's default (`batch_mb`)


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


def cell_slots(config: WorldConfig, budget_mb: float, episodes: int) -> int:
    """How many worlds a cell's `episodes` are played on: as many as fit `budget_mb`, at most one per episode."""
    return min(worlds_per_batch(config, budget_mb), episodes)


def episode_keys(seed: int, cell_index: int, episodes: list[tuple[int, int]]) -> list[tuple[int, int, int, int]]:
    """The keys of the episodes (map, repeat) of a cell: (seed, cell, map, repeat), from which each episode's own
    streams are seeded (searchrl/controllers/episodes.py), so how a cell is split into batches, threads or shards
    changes no episode."""
    return [(seed, cell_index, m, r) for m, r in episodes]


def run_cell(
    controller_factory: ControllerFactory,
    world: WorldConfig,
    cell: Cell,
    cell_index: int,
    maps: int,
    repeats: int,
    seed: int,
    budget_mb: float = BATCH_MB,
    needs_observation: bool = True,
    on_steps: Callable[[int], None] | None = None,
    on_done: Callable[[WorldState, np.ndarray, np.ndarray], None] | None = None,
    scenario: Scenario = PAPER,
) -> pd.DataFrame:
    """One row per episode (COLUMNS from n on). Every repeat of a map starts from
    the same world (map, targets and start cells come from the map seed); repeats differ in the step draws and the
    controller's own randomness, each episode's from its own streams (`episode_keys`; `controller_factory(config,
    streams)` builds a controller drawing from them). As many worlds as fit `budget_mb` step together, each
    starting the cell's next episode when its own ends (`play_episodes`), so `budget_mb` changes how many step
    together and nothing else. `on_steps(agent_steps)` counts the agent-steps of running episodes after each step;
    `on_done(state, first, playing)` sees the batch's state when the worlds in `first` (K,) bool end their
    episodes, `playing` (K,) the index of each world's episode in the cell (its row: analysis/missed_targets.py
    reads it). `scenario` draws each map's obstacles and targets (the paper's by
    default): a map seed gives the same prior under every scenario."""
    config = cell_config(world, cell)
    episodes = [(m, r) for m in range(maps) for r in range(repeats)]

    def count(_: SearchWorld, counted: np.ndarray) -> None:
        on_steps(int(counted.sum()) * config.n_agents)

    seeds = [map_seed(seed, cell_index, m) for m, _ in episodes]
    final = play_episodes(
        controller_factory,
        config,
        seeds,
        episode_keys(seed, cell_index, episodes),
        scenario,
        needs_observation,
        count if on_steps else None,
        on_done,
        slots=cell_slots(config, budget_mb, len(episodes)),
    )
    rows = []
    for e, (_, r) in enumerate(episodes):
        rows.append(
            {
                "n": cell.n,
                "N": cell.n_agents,
                "targets": cell.n_targets,
                "map_seed": seeds[e],
                "repeat": r,
                **{name: final[name][e] for name in ("found_fraction", "L", "R", "F", "M_bar", "prior_quality")},
                "blocked": final["collisions"][e] / max(1, final["L"][e] * cell.n_agents),
                "stale": final["stale"][e] / max(1, final["L"][e] * cell.n_agents),
            }
        )
    return pd.DataFrame(rows)
