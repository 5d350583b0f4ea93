"""The per-map search bound of evaluation episodes (searchrl/world/bound.py), from a cell and its map seeds.

An episode's map (p, u, obstacles, target count) is a function of the cell and its map seed (runner.run_cell resets
each world from `np.random.default_rng(map_seed)`), so the bound is computed from the same seed, for new
evaluations and for folders written before it existed alike. `bound_fraction` = bound / targets sits beside an
episode's `found_fraction`; a cell's efficiency is its mean found fraction over its mean bound fraction.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from searchrl.evaluate.grid import Cell
from searchrl.evaluate.runner import cell_config
from searchrl.world.bound import search_bound, team_reach
from searchrl.world.config import WorldConfig
from searchrl.world.reset import reset_world
from searchrl.world.state import allocate

BOUND_DRAWS = 1000  # placements per map: a standard error of about 0.075 targets of 32 at n = 160


def map_prior(config: WorldConfig, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p, u, free) (n, n) of the map an evaluation draws from `seed` for a cell's config."""
    state = allocate(config, 1)
    reset_world(config, state, 0, np.random.default_rng(seed))
    n, h = int(state.size[0]), state.halo
    inner = (0, slice(h, h + n), slice(h, h + n))
    return state.p[inner].astype(np.float64), state.u[inner].astype(np.float64), ~state.blocked[inner]


def cell_bounds(world: WorldConfig, cell: Cell, seeds: list[int], draws: int = BOUND_DRAWS) -> pd.DataFrame:
    """One row per map seed: `bound` (expected targets at most), `bound_stderr`, `bound_fraction`, `reach`."""
    config = cell_config(world, cell)
    reach = team_reach(cell.n_agents, config.max_steps, config.n_actions)
    rows = []
    for seed in seeds:
        p, u, free = map_prior(config, seed)
        bound = search_bound(p, u, free, cell.n_targets, reach, draws, np.random.default_rng([seed, 29]))
        rows.append({"map_seed": seed, "bound": bound.expected, "bound_stderr": bound.stderr,
                     "bound_fraction": bound.expected / cell.n_targets, "reach": bound.reach})  # fmt: skip
    return pd.DataFrame(rows)
