"""Summaries with bootstrap confidence intervals, Table 3 layouts, and training curves."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from searchrl.evaluate.paired import bootstrap_mean_ci
from searchrl.evaluate.paired import paired_margins as paired_margins  # the notebooks' too
from searchrl.world.scenario import PAPER

GROUP = ["controller", "model", "n", "N"]
# Where search is hard (issue 29): the largest team per world size whose cells are far from saturated.
HARD_CELLS = {40: 2, 80: 8, 160: 32}  # n = 40 with N <= 2, n = 80 with N <= 8, n = 160 with N <= 32: 12 cells


def is_hard(frame: pd.DataFrame) -> pd.Series:
    """Which rows of a frame with columns n and N are hard cells (HARD_CELLS)."""
    return frame["N"] <= frame["n"].map(HARD_CELLS).fillna(0)


def efficiency_summary(summary: pd.DataFrame) -> pd.DataFrame:
    """Per (controller, model): the mean found fraction, bound and efficiency over the hard cells, and the mean
    efficiency over every cell whose bound is below 0.995 (where there is something the team could miss)."""
    rows = []
    for key, block in summary.groupby(["controller", "model"]):
        hard, open_cells = block[is_hard(block)], block[block["bound"] < 0.995]
        rows.append(
            {
                "controller": key[0],
                "model": key[1],
                "hard found": hard["mean"].mean(),
                "hard bound": hard["bound"].mean(),
                "hard efficiency": hard["efficiency"].mean(),
                "unsaturated cells": len(open_cells),
                "their efficiency": open_cells["efficiency"].mean(),
            }
        )
    return pd.DataFrame(rows).set_index(["controller", "model"])


def worst_tenth(episodes: pd.DataFrame) -> float:
    """The worst-10 % tail of episodes with columns n, N, map_seed and found_fraction: per cell (n, N), the mean of
    its worst tenth of maps (at least one; a map's rows, its repeats or scenarios, averaged first), averaged over
    the cells. How badly a controller can fail, where a mean hides it."""
    tails = []
    for _, cell in episodes.groupby(["n", "N"]):
        values = np.sort(cell.groupby("map_seed")["found_fraction"].mean().to_numpy())
        tails.append(values[: max(1, int(np.ceil(0.1 * len(values))))].mean())
    return float(np.mean(tails))


def summarize(episodes: pd.DataFrame, metric: str = "found_fraction", n_boot: int = 2000) -> pd.DataFrame:
    """One row per (controller, model, n, N): mean of `metric` with a 95 % CI. Repeats of a map are averaged
    first, so the bootstrap resamples maps, the independent units. Where episodes have their map's search bound
    (`bound_fraction`, searchrl/evaluate/cell_bounds.py), also `bound` (its mean over the cell's maps) and `efficiency`
    = mean / bound with its CI (`efficiency_low`, `efficiency_high`: the found fraction's CI over the same bound,
    whose own Monte Carlo error is far smaller)."""
    values = [metric, "bound_fraction"] if "bound_fraction" in episodes else [metric]
    per_map = episodes.groupby([*GROUP, "map_seed"], as_index=False)[values].agg(lambda v: v.mean(skipna=False))
    rows = []
    for key, group in per_map.groupby(GROUP):
        mean, low, high = bootstrap_mean_ci(group[metric].to_numpy(), n_boot)
        rows.append({**dict(zip(GROUP, key, strict=True)), "mean": mean, "low": low, "high": high, "maps": len(group)})
        if "bound_fraction" in group:  # NaN for a cell run before bounds were recorded: no efficiency
            rows[-1]["bound"] = bound = group["bound_fraction"].mean(skipna=False)
            rows[-1].update(efficiency=mean / bound, efficiency_low=low / bound, efficiency_high=high / bound)
    summary = pd.DataFrame(rows)
    if "scenario" in episodes:  # what each (controller, model) ran under: a comparison with the paper needs its own
        held = episodes.groupby(["controller", "model"])["scenario"].agg(lambda v: "+".join(sorted(set(v))))
        summary = summary.merge(held.reset_index(), on=["controller", "model"], how="left")
    return summary


def with_bounds(summary: pd.DataFrame, bounds: pd.DataFrame) -> pd.DataFrame:
    """`summary` (summarize's columns, e.g. a table3.csv) with the grid's per-cell `bound` (analysis/bounds.py's
    bounds.csv: the mean bound fraction over the same maps) and the efficiency columns `summarize` gives; where
    `bounds` has the detection bound, also `detection_bound` and `detection_efficiency` (mean / it)."""
    extra = [c for c in ("detection_bound", "detection_mc_stderr") if c in bounds]
    merged = summary.drop(columns=["bound", *extra], errors="ignore").merge(
        bounds[["n", "N", "bound", "mc_stderr", *extra]], on=["n", "N"], how="left", validate="many_to_one"
    )
    merged = merged.assign(
        efficiency=merged["mean"] / merged["bound"],
        efficiency_low=merged["low"] / merged["bound"],
        efficiency_high=merged["high"] / merged["bound"],
    )
    if "detection_bound" in merged:
        merged["detection_efficiency"] = merged["mean"] / merged["detection_bound"]
    return merged


def table3(summary: pd.DataFrame, value: str = "mean") -> pd.DataFrame:
    """Table 3 layout: rows N, columns n, one block per (controller, model)."""
    return summary.pivot_table(index=["controller", "model", "N"], columns="n", values=value)


def paper_table3(path: str | Path) -> pd.DataFrame:
    """The paper's Table 3 as a tidy frame: model, n, N, found_fraction."""
    frame = pd.read_csv(path)
    return frame.rename(columns={"world_size": "n", "n_agents": "N"})


def beside_paper(summary: pd.DataFrame, paper: pd.DataFrame) -> pd.DataFrame:
    """Our found fraction (with CI) beside the paper's for the same model and cell; `model` matched
    case-insensitively (the paper's A, B, C, diagonal). Only rows of the paper's scenario (a summary's `scenario`
    column, where it has one) are compared: the paper's numbers are of the open grid with the prior right."""
    ours = summary.assign(key=summary["model"].str.lower())
    if "scenario" in ours:
        ours.loc[ours["scenario"] != PAPER.label, "key"] = None
    theirs = paper.assign(key=paper["model"].str.lower()).rename(columns={"found_fraction": "paper"})
    merged = ours.merge(theirs[["key", "n", "N", "paper"]], on=["key", "n", "N"], how="left").drop(columns="key")
    return merged.assign(diff=merged["mean"] - merged["paper"])


# The teacher term's cross-entropy toward the teacher's actions (logged whatever its weight, 0 included) and the
# critic's explained variance: how far RL has moved the policy from its teacher, and how good its advantages are.
TRAIN_DIAGNOSTICS = ("train/imitation_loss", "train/explained_variance", "train/entropy_loss")


def training_curves(run_dirs: list[str | Path]) -> pd.DataFrame:
    """Tidy frame (run, model, setting, seed, step, metric, value) of team metrics, validation and the PPO
    diagnostics of TRAIN_DIAGNOSTICS from each run's progress.csv. `setting` names the run's config less its seed
    (and what a resume may change): the runs of one setting are its seeds."""
    frames = []
    for run in map(Path, run_dirs):
        progress = pd.read_csv(run / "progress.csv")
        model, setting, seed = _model_name(run), *_setting(run)
        keep = [c for c in progress.columns if c.startswith(("team/", "val/")) or c in TRAIN_DIAGNOSTICS]
        long = progress.melt(id_vars=["time/total_timesteps"], value_vars=keep, var_name="metric").dropna()
        long = long.rename(columns={"time/total_timesteps": "step"})
        frames.append(long.assign(run=run.name, model=model, setting=setting, seed=seed))
    if not frames:
        raise FileNotFoundError("no run directories given")
    return pd.concat(frames, ignore_index=True)


# What differs between the seeds of one setting besides the seed: a resume's settings and the run's own paths
NOT_SETTING = (
    "seed",
    "resume",
    "total_timesteps",
    "threads",
    "device",
    "progress_bar",
    "keep_checkpoints",
    "logger",
    "hydra",
)


def _setting(run: Path) -> tuple[str, int]:
    """(the run's setting: its model and a digest of its config less NOT_SETTING, its seed)."""
    config = run / "config.yaml"
    if not config.exists():
        return run.name, 0
    values = OmegaConf.to_container(OmegaConf.load(config))
    kept = {k: v for k, v in values.items() if k not in NOT_SETTING}
    digest = hashlib.sha256(json.dumps(kept, sort_keys=True, default=str).encode()).hexdigest()[:6]
    return f"{_model_name(run)}:{digest}", int(values.get("seed", 0))


def _model_name(run: Path) -> str:
    config = run / "config.yaml"
    if not config.exists():
        return "unknown"
    model = OmegaConf.load(config).get("model")
    return str(model.name) if model else "unknown"


def markdown(frame: pd.DataFrame, digits: int = 3) -> str:
    """A pipe table of `frame` (index included), numbers rounded; NaN shown as an en dash."""
    flat = frame.reset_index()
    header = [str(c) if not isinstance(c, tuple) else " ".join(map(str, c)).strip() for c in flat.columns]

    def cell(v: object) -> str:
        if isinstance(v, float):
            return "–" if np.isnan(v) else f"{v:.{digits}f}"
        return str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in flat.itertuples(index=False)]
    return "\n".join(lines) + "\n"
