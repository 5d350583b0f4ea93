"""Paired comparisons of two evaluations on the maps they share: per cell, the mean per-map difference with its
percentile-bootstrap 95 % CI over maps, and a verdict. Evaluations with the same seed and grid play the same maps (a
map's seed depends only on the cell's index in the grid and the map's), so their per-map differences pair.

The evaluation app prints these against a `baseline=` folder at its end; the notebooks (searchrl/reporting/stats.py)
use the same functions.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def bootstrap_mean_ci(
    per_map: np.ndarray, n_boot: int = 2000, level: float = 0.95, seed: int = 0
) -> tuple[float, float, float]:
    """(mean, low, high) of the mean of `per_map` values (maps are the independent units), percentile bootstrap."""
    values = np.asarray(per_map, float)
    if values.size == 0:
        raise ValueError("bootstrap of an empty sample")
    rng = np.random.default_rng(seed)
    means = values[rng.integers(0, values.size, size=(n_boot, values.size))].mean(axis=1)
    tail = (1 - level) / 2
    return float(values.mean()), float(np.quantile(means, tail)), float(np.quantile(means, 1 - tail))


def paired_margins(
    episodes: pd.DataFrame,
    mine: str,
    baseline: str,
    metric: str = "found_fraction",
    n_boot: int = 2000,
    saturated: float = 0.995,
    min_maps: int = 20,
) -> pd.DataFrame:
    """Controller `mine` minus controller `baseline`, cell by cell, on the maps both ran (evaluations with the
    same seed and grid share their maps: a seed depends only on the cell and map index; cells or maps only one
    side ran are left out). Repeats are averaged per map, the per-map differences bootstrapped. `verdict`:
    "better" / "worse" when the 95 % CI excludes 0, "tie" otherwise, "saturated" for a tie where both means are
    at least `saturated` (nothing left to find), and "too few maps" below `min_maps` paired maps. The CIs are
    per cell, not corrected for comparing many cells."""
    per_map = episodes.groupby(["controller", "model", "n", "N", "map_seed"], as_index=False)[metric].mean()
    sides = []
    for name in (mine, baseline):
        side = per_map[per_map.controller == name]
        if side.empty:
            raise ValueError(f"no episodes of controller {name!r} to compare")
        if side.model.nunique() > 1:
            raise ValueError(
                f"controller {name!r} was evaluated with several models {sorted(side.model.unique())}:"
                " pass episodes of one"
            )
        sides.append(side.drop(columns=["controller", "model"]))
    joined = sides[0].merge(sides[1], on=["n", "N", "map_seed"], suffixes=("_mine", "_base"))
    if joined.empty:
        raise ValueError(f"{mine!r} and {baseline!r} share no map: were they evaluated with the same seed and grid?")
    rows = []
    for (n, agents), group in joined.groupby(["n", "N"]):
        diff, low, high = bootstrap_mean_ci((group[f"{metric}_mine"] - group[f"{metric}_base"]).to_numpy(), n_boot)
        ours, theirs = group[f"{metric}_mine"].mean(), group[f"{metric}_base"].mean()
        verdict = "better" if low > 0 else "worse" if high < 0 else "tie"
        if verdict == "tie" and min(ours, theirs) >= saturated:
            verdict = "saturated"
        if len(group) < min_maps:
            verdict = "too few maps"
        rows.append(
            {
                "controller": mine,
                "baseline": baseline,
                "n": n,
                "N": agents,
                "mine": ours,
                "base": theirs,
                "diff": diff,
                "low": low,
                "high": high,
                "maps": len(group),
                "verdict": verdict,
            }
        )
    return pd.DataFrame(rows)
