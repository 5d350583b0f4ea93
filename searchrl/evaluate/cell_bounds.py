"""The per-map search bound of evaluation episodes (searchrl/world/bound.py), from a cell and its map seeds.

An episode's map (p, u, obstacles, target count) is a function of the cell and its map seed (runner.run_cell resets
each world from `np.random.default_rng(map_seed)`), so the bound is computed from the same seed. `bound_fraction` =
bound / targets sits beside an episode's `found_fraction`; a cell's efficiency is its mean found fraction over its
mean bound fraction (`searchrl.reporting.stats.summarize`).

Bounds are kept in a cache folder (`runs/bounds/` by default), one file per cell and draw count, each row keyed by
its map seed, the digest of the map it was computed on, and the team's reach: the maps do not depend on the model
or the sensing constant, so every evaluation of the grid reuses the first one's bounds, and a row is only reused
for the very map and reach it was computed for. A row with the detection bound holds it for both move sets
(cardinal and diagonal, `MOVE_SETS`, from the same draws); a world reads the one of its own moves.

`analysis/bounds.py` computes the whole grid's (`grid_bounds`) into the per-cell table that docs/results.md joins
with its Table 3 means.
"""

from __future__ import annotations

import hashlib
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from searchrl.atomic import write_atomic
from searchrl.evaluate.grid import Cell, map_seed
from searchrl.evaluate.runner import cell_config
from searchrl.world.bound import detection_budget, search_bound, team_reach
from searchrl.world.config import WorldConfig
from searchrl.world.reset import draw_world
from searchrl.world.scenario import PAPER, Scenario

BOUND_DRAWS = 1000  # placements per map: a standard error of about 0.075 targets of 32 at n = 160
# The paper grid's bounds (seed 0, 100 maps a cell, BOUND_DRAWS), shipped: a cache without a cell's file reads that
# cell's rows from here (`analysis/bounds.py --cache runs/reference/bounds` remakes them)
REFERENCE_BOUNDS = Path("runs/reference/bounds")
BOUND_COLUMNS = ["bound", "bound_stderr", "bound_fraction"]
MOVE_SETS = {"cardinal": False, "diagonal": True}  # WorldConfig.diagonal of each move set the cache holds


def map_prior(config: WorldConfig, seed: int, scenario: Scenario = PAPER) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p, u, free) (n, n) of the map an evaluation draws from `seed` for a cell's config under `scenario`: p and u
    as a world holds them (float32) in float64. Drawn alone, not written into a world's arrays (a world's beliefs
    are N · 2 · (n + 2h)² floats)."""
    drawn = draw_world(config, config.n_agents, np.random.default_rng(seed), scenario)
    return drawn.p.astype(np.float32).astype(np.float64), drawn.u.astype(np.float32).astype(np.float64), drawn.free


def map_digest(p: np.ndarray, u: np.ndarray, free: np.ndarray, targets: int) -> str:
    """A short hash of everything the bound depends on besides the reach: the prior, the obstacles, the count."""
    digest = hashlib.sha256(np.int64(targets).tobytes())
    for array in (p, u, free):
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()[:16]


def _known_rows(path: Path | None) -> pd.DataFrame | None:
    """The rows cached for a cell (its file in the cache), else those shipped for it (`REFERENCE_BOUNDS`: read
    only, what is computed beside them is written to the cache with them), else None."""
    if path is None:
        return None
    source = next((p for p in (path, REFERENCE_BOUNDS / path.name) if p.exists()), None)
    return _read_cache(source) if source is not None else None


def _read_cache(path: Path) -> pd.DataFrame | None:
    """The cached rows of a cell, or None when the file is damaged: its rows are computed again and the file
    replaced (a cache is never a reason to stop)."""
    try:
        return pd.read_parquet(path)
    except Exception as err:  # pyarrow's errors for a damaged file have no common base but Exception
        print(f"note: {path} cannot be read ({type(err).__name__}); its bounds are computed again", file=sys.stderr)
        return None


def cell_bounds(
    world: WorldConfig,
    cell: Cell,
    seeds: list[int],
    draws: int = BOUND_DRAWS,
    cache: str | Path | None = None,
    detection: bool = False,
    scenario: Scenario = PAPER,
    workers: int = 1,
) -> pd.DataFrame:
    """One row per map seed: `bound` (expected targets at most), `bound_stderr`, `bound_fraction`, `reach`; with
    `detection` also the detection bound of the world's moves (`detection_bound`, `detection_stderr`,
    `detection_fraction`). With `cache`, rows computed before for the same map, reach and draws are read from it
    and new ones added (a cache without the cell's file starts from the shipped rows, `REFERENCE_BOUNDS`); the new
    ones are computed on `workers` threads (each map from its own seed's generator, so
    the count changes no value; numpy draws the Gumbel noise, most of the time, outside the GIL). The bound assumes
    §4.1.4's placement from the prior: under a scenario whose targets do not follow the prior
    (`Scenario.targets_follow_prior`) its columns are NaN, as nothing bounds them from the prior."""
    if not scenario.targets_follow_prior:
        columns = ["bound", "bound_stderr", "bound_fraction", "reach"]
        columns += ["detection_bound", "detection_stderr", "detection_fraction"] if detection else []
        frame = pd.DataFrame({"map_seed": np.asarray(seeds, np.int64)} | {c: np.nan for c in columns})
        return frame.astype({c: np.float64 for c in columns})
    config = cell_config(world, cell)
    reach = team_reach(cell.n_agents, config.max_steps, config.n_actions)
    budgets = (
        [
            detection_budget(cell.n_agents, config.max_steps, replace(config, diagonal=d).n_actions)
            for d in MOVE_SETS.values()
        ]
        if detection
        else []
    )
    own = "diagonal" if config.diagonal else "cardinal"
    path = Path(cache) / f"{cell.key}_draws{draws}.parquet" if cache is not None else None
    known = _known_rows(path)
    if known is not None and not {"map_seed", "digest", "team_reach"} <= set(known.columns):
        known = None  # a cache file of another layout: computed afresh and replaced
    if known is not None:  # a detection bound without its move set (before MOVE_SETS): computed again if asked
        known = known.drop(columns=["detection_bound", "detection_stderr"], errors="ignore")
    maps = {seed: map_prior(config, seed, scenario) for seed in seeds}
    rows: dict[int, dict] = {}
    for seed, (p, u, free) in maps.items():
        digest = map_digest(p, u, free, cell.n_targets)
        if known is not None:
            match = known[(known.map_seed == seed) & (known.digest == digest) & (known.team_reach == reach)]
            hit = match.iloc[0].to_dict() if len(match) else None
            if hit is not None and detection and pd.isna(hit.get(f"detection_bound_{own}", np.nan)):
                known, hit = known.drop(index=match.index[0]), None  # computed without it: again, with it
            if hit is not None:
                rows[seed] = hit

    def compute(seed: int) -> dict:
        p, u, free = maps[seed]
        rng = np.random.default_rng([seed, 29])  # the same draws with or without the detection bound
        bound = search_bound(p, u, free, cell.n_targets, reach, draws, rng, budgets)
        hit = {
            "map_seed": seed,
            "digest": map_digest(p, u, free, cell.n_targets),
            "team_reach": reach,
            "reach": bound.reach,
            "bound": bound.expected,
            "bound_stderr": bound.stderr,
        }
        for name, value, stderr in zip(
            MOVE_SETS if detection else [], bound.detection, bound.detection_stderr, strict=True
        ):
            hit |= {f"detection_bound_{name}": value, f"detection_stderr_{name}": stderr}
        return hit

    missing = [seed for seed in maps if seed not in rows]
    with ThreadPoolExecutor(max(1, min(workers, len(missing)))) as pool:
        new = list(pool.map(compute, missing))
    rows |= dict(zip(missing, new, strict=True))
    if path is not None and new:
        merged = pd.concat([known, pd.DataFrame(new)] if known is not None else [pd.DataFrame(new)])
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, lambda tmp: merged.reset_index(drop=True).to_parquet(tmp))
    frame = pd.DataFrame([rows[seed] for seed in seeds]).astype({"map_seed": np.int64, "reach": np.int64})
    frame["bound_fraction"] = frame["bound"] / cell.n_targets
    if not detection:
        return frame[["map_seed", *BOUND_COLUMNS, "reach"]]
    frame["detection_bound"] = frame[f"detection_bound_{own}"]
    frame["detection_stderr"] = frame[f"detection_stderr_{own}"]
    frame["detection_fraction"] = frame["detection_bound"] / cell.n_targets
    return frame[["map_seed", *BOUND_COLUMNS, "reach", "detection_bound", "detection_stderr", "detection_fraction"]]


def grid_bounds(
    world: WorldConfig, cells: list[Cell], maps: int, seed: int, draws: int, cache: str | Path | None
) -> pd.DataFrame:
    """Per cell of the grid: n, N, targets, maps, reach, the mean bound fraction over its maps, the Monte Carlo
    standard error of that mean, and the smallest and largest map's; then the detection bound's `budget`, mean
    fraction and standard error, for the moves of `world`."""
    rows = []
    for index, cell in enumerate(cells):
        seeds = [map_seed(seed, index, m) for m in range(maps)]
        per_map = cell_bounds(world, cell, seeds, draws, cache, detection=True)
        fraction = per_map["bound_fraction"]
        mc = np.sqrt((per_map["bound_stderr"] ** 2).sum()) / len(per_map) / cell.n_targets
        config = cell_config(world, cell)
        rows.append(
            {
                "n": cell.n,
                "N": cell.n_agents,
                "targets": cell.n_targets,
                "maps": len(per_map),
                "reach": int(per_map["reach"].iloc[0]),
                "bound": fraction.mean(),
                "mc_stderr": mc,
                "min": fraction.min(),
                "max": fraction.max(),
                "budget": detection_budget(cell.n_agents, config.max_steps, config.n_actions),
                "detection_bound": per_map["detection_fraction"].mean(),
                "detection_mc_stderr": np.sqrt((per_map["detection_stderr"] ** 2).sum())
                / len(per_map)
                / cell.n_targets,
            }
        )
        print(f"{cell.key}: bound fraction {fraction.mean():.3f}", flush=True)
    return pd.DataFrame(rows)
