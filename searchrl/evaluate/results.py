"""Loading evaluation results into one tidy frame."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from searchrl.evaluate.cell_checks import check_cell
from searchrl.evaluate.grid import cell_files
from searchrl.evaluate.record import CELL_SETTINGS, setting_differences
from searchrl.migrations import EVALUATION_RECORD_ADDED, upgrade_cell
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import Scenario


def world_config_of(out_dir: str | Path) -> WorldConfig | None:
    """The world settings a heuristic's evaluation folder records (evaluation.yaml), or None (a checkpoint's
    record names the file, whose run holds its world)."""
    record = Path(out_dir) / "evaluation.yaml"
    world = OmegaConf.to_container(OmegaConf.load(record)).get("world") if record.exists() else None
    return WorldConfig.from_dict(world) if world else None


def world_of(out_dir: str | Path) -> str:
    """The sensing label of a folder whose cells predate the `world` column, else "unknown"."""
    config = world_config_of(out_dir)
    return config.sensing_label if config else "unknown"


# What a result row is grouped under in every table (searchrl/reporting/stats.py): two folders sharing it are named
# apart, whatever else differs between them (the world, the scenario, the settings).
LABEL = ["controller", "model"]


def load(*out_dirs: str | Path) -> pd.DataFrame:
    """Every episode row of the given evaluation directories (`<dir>/cells/<cell>.parquet`), one frame.

    Two folders whose rows carry the same label (controller, model) hold different evaluations (greedy and
    greedy_target are both `greedy`; a clone and its RL policy both `policy:b`; one controller in two worlds or
    scenarios): merged, their maps would count twice under one name. Their controllers are named apart as
    `<controller>@<folder>` (the folder's name, or its path where the names are equal too), and a note says so."""
    frames = []
    for d in out_dirs:
        first: tuple[Path, dict] | None = None
        for f in cell_files(d):
            try:
                frame = pd.read_parquet(f)
            except Exception as err:  # pyarrow's errors for a damaged file have no common base but Exception
                raise ValueError(
                    f"{f} cannot be read as a cell's results ({type(err).__name__}); remove it and "
                    "rerun the evaluation into its folder to write it again"
                ) from None
            settings = frame.attrs.get(CELL_SETTINGS)
            if settings is not None and first is None:
                first = (f, settings)
            elif settings is not None and (differ := setting_differences(settings, first[1], {})):
                raise ValueError(
                    f"{f} and {first[0].name} hold results of other settings ({'; '.join(differ)}): "
                    "one folder holds one evaluation; remove the cell that does not belong"
                )
            frame = upgrade_cell(frame, lambda folder=d: world_of(folder))  # an older cell's columns
            check_cell(frame, f)  # a damaged or edited cell is refused, never summarised
            frame["folder"] = str(d)
            frames.append(frame)
    if not frames:
        raise FileNotFoundError(f"no cells/*.parquet under {[str(d) for d in out_dirs]}")
    return _named_apart(frames)


def _named_apart(frames: list[pd.DataFrame]) -> pd.DataFrame:
    """The frames (each with a `folder` column) as one, controllers whose label two folders share renamed per
    folder."""
    episodes = pd.concat(frames, ignore_index=True)
    keys = episodes[LABEL].astype(str).agg(" | ".join, axis=1)
    per_label = episodes.groupby(keys)["folder"].nunique()
    clash = keys.isin(per_label[per_label > 1].index)
    if clash.any():
        folders = sorted(episodes.loc[clash, "folder"].unique())
        names = [Path(f).name for f in folders]
        suffix = dict(zip(folders, names if len(set(names)) == len(names) else folders, strict=True))
        episodes.loc[clash, "controller"] += "@" + episodes.loc[clash, "folder"].map(suffix)
        print(
            f"note: {', '.join(folders)} hold results under one label: each named apart by its folder "
            f"({', '.join(sorted(episodes.loc[clash, 'controller'].unique()))})",
            file=sys.stderr,
        )
    return episodes.drop(columns="folder")


def coverage(out_dir: str | Path) -> dict[str, object]:
    """What an evaluation folder's results cover, from its record and cells: controller, scenario label, seed, maps
    and repeats per cell, the cells held and those of its grid it lacks (cell keys). Empty for a folder without a
    readable record."""
    from searchrl.evaluate.grid import table2_cells

    record_path = Path(out_dir) / "evaluation.yaml"
    try:
        record = OmegaConf.to_container(OmegaConf.load(record_path))
        grid = record["grid"]
        cells = table2_cells(grid["world_sizes"], grid["n_targets"], grid["n_distributions"], grid["max_agents"])
    except Exception:  # no record, or one made before it held these: nothing to say beyond the cells
        return {}
    agents = grid.get("agents")
    wanted = [c.key for c in cells if agents is None or c.n_agents in agents]
    held = {f.stem for f in cell_files(out_dir)}
    scenario = Scenario.from_dict(record.get("scenario") or EVALUATION_RECORD_ADDED["scenario"]).label
    return {
        "controller": record.get("controller"),
        "scenario": scenario,
        "seed": record.get("seed"),
        "maps": grid["maps_per_cell"],
        "repeats": grid["repeats"],
        "cells": [k for k in wanted if k in held],
        "missing": [k for k in wanted if k not in held],
    }


def coverage_line(out_dir: str | Path) -> str:
    """One line saying what a folder's results cover (`coverage`), for the head of every table made from it."""
    c = coverage(out_dir)
    if not c:
        return f"{out_dir}: {len(cell_files(out_dir))} cells (no record says of which grid, seed or scenario)"
    # the shorter list: the cells missing, or those held (a one-cell evaluation of the grid holds one of 30)
    which = (
        ""
        if not c["missing"]
        else f"; missing {', '.join(c['missing'])}"
        if len(c["missing"]) <= len(c["cells"])
        else f": {', '.join(c['cells'])}"
        if c["cells"]
        else ""
    )
    return (
        f"{c['controller']}: scenario {c['scenario']}, seed {c['seed']}, {c['maps']} maps x {c['repeats']} "
        f"repeats per cell, {len(c['cells'])} of {len(c['cells']) + len(c['missing'])} cells{which}"
    )


def cell_table(out_dir: str | Path) -> str:
    """What an evaluation folder measured, as the app prints it at its end: its `coverage_line`, then per cell
    (n, N) the maps, the mean found fraction with its 95 % CI over maps (the per-map means' normal approximation,
    1.96 standard errors; NaN with one map) and the mean search bound of the same maps where recorded."""
    if not cell_files(out_dir):  # a shard with no cell of this folder: nothing measured yet
        return coverage_line(out_dir)
    frame = load(out_dir)
    bound = "bound_fraction" in frame and frame["bound_fraction"].notna().any()
    column = "bound_fraction" if bound else "found_fraction"
    per_map = frame.groupby(["n", "N", "map_seed"]).agg(found=("found_fraction", "mean"), bound=(column, "mean"))
    rows = []
    for (n, agents), maps in per_map.groupby(level=["n", "N"]):
        half = 1.96 * maps["found"].std(ddof=1) / len(maps) ** 0.5 if len(maps) > 1 else float("nan")
        mean = maps["found"].mean()
        rows.append(
            {
                "n": n,
                "N": agents,
                "maps": len(maps),
                "found": round(mean, 3),
                "95% CI": f"[{mean - half:.3f}, {mean + half:.3f}]",
                **({"bound": round(maps["bound"].mean(), 3)} if bound else {}),
            }
        )
    return f"{coverage_line(out_dir)}\n{pd.DataFrame(rows).to_string(index=False)}"


def paired_table(out_dir: str | Path, baseline: str | Path) -> str:
    """A folder against a baseline folder on the maps both played (searchrl/evaluate/paired.py), as the app prints
    it at its end: per cell the maps paired, the two means, the difference with its 95 % bootstrap CI and the
    verdict, then the count of each verdict. One line when they share no cell yet."""
    from searchrl.evaluate.paired import paired_margins

    if not cell_files(out_dir) or not cell_files(baseline):
        return f"against {baseline}: no cell of both yet"
    mine, base = load(out_dir), load(baseline)
    name, other = str(mine["controller"].iloc[0]), str(base["controller"].iloc[0])
    if other == name:
        other = base["controller"] = f"{name} (baseline)"
    shared = set(zip(mine.n, mine.N, strict=True)) & set(zip(base.n, base.N, strict=True))
    if not shared:
        return f"against {baseline}: no cell of both yet"
    table = paired_margins(pd.concat([mine, base], ignore_index=True), name, other)
    counts = table["verdict"].value_counts()
    verdicts = ("better", "tie", "worse", "saturated", "too few maps")
    summary = ", ".join(f"{verdict} on {counts[verdict]}" for verdict in verdicts if verdict in counts)
    rows = pd.DataFrame(
        {
            "n": table.n,
            "N": table.N,
            "maps": table.maps,
            "mine": table["mine"].round(3),
            "baseline": table["base"].round(3),
            "diff": [f"{d:+.3f}" for d in table["diff"]],
            "95% CI": [f"[{lo:+.3f}, {hi:+.3f}]" for lo, hi in zip(table.low, table.high, strict=True)],
            "verdict": table.verdict,
        }
    )
    return f"against {other} ({baseline}), paired on the same maps: {summary}\n{rows.to_string(index=False)}"
