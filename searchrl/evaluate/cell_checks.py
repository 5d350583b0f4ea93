"""Every cell's rows checked on read: a damaged or edited cell is refused, never summarised.

A cell file `<out_dir>/cells/n<n>_N<N>.parquet` holds one row per episode (searchrl/evaluate/runner.py). What an
episode can be bounds its numbers: its found fraction is a share of its targets (in [0, 1], a whole number of them),
its length at least one step, its communication pairs and bound not negative, its bound's fraction in [0, 1] (the
bound's columns may be NaN: a scenario whose prior misleads has none); the cell's n and N are its name's, and no
(map, repeat) appears twice. A row outside these was not written by an
evaluation: the file is refused in one line naming it, the column, the row and the value, with what to do.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

# (column, lowest, highest) an episode's number lies in; None: unbounded on that side
MAY_BE_NAN = ("bound", "bound_stderr", "bound_fraction")
BOUNDS = (
    ("found_fraction", 0.0, 1.0),
    ("bound_fraction", 0.0, 1.0),
    ("targets", 1, None),
    ("L", 1, None),
    ("F", 0, None),
    ("M_bar", 0.0, None),
    ("bound", 0.0, None),
    ("bound_stderr", 0.0, None),
    ("repeat", 0, None),
)
NAME = re.compile(r"n(\d+)_N(\d+)\.parquet")


class DamagedCell(ValueError):
    """A cell whose rows no evaluation writes; its message is one line."""


def _refuse(path: Path, what: str) -> None:
    raise DamagedCell(f"{path}: {what}: the cell is damaged; remove it and rerun the evaluation into its folder")


def check_cell(frame: pd.DataFrame, path: str | Path) -> None:
    """DamagedCell naming the first row of `frame` (the rows of cell file `path`) that no episode can have."""
    path = Path(path)
    if frame.empty:
        _refuse(path, "it holds no episode")
    for column, low, high in BOUNDS:
        if column not in frame:
            continue
        values = pd.to_numeric(frame[column], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(values) & ~(np.isnan(values) & (column in MAY_BE_NAN))
        if low is not None:
            bad |= values < low
        if high is not None:
            bad |= values > high
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            allowed = f"[{low}, {high}]" if high is not None else f">= {low}"
            _refuse(path, f"{column}={frame[column].iloc[row]} in row {row} is not allowed ({allowed})")
    if "found_fraction" in frame and "targets" in frame:
        found = frame["found_fraction"].to_numpy(float) * frame["targets"].to_numpy(float)
        off = np.abs(found - np.round(found)) > 1e-6
        if off.any():
            row = int(np.flatnonzero(off)[0])
            value, targets = frame["found_fraction"].iloc[row], frame["targets"].iloc[row]
            _refuse(path, f"found_fraction={value} in row {row} is no whole number of its {targets} targets")
    named = NAME.fullmatch(path.name)
    if named and {"n", "N"} <= set(frame):
        n, agents = int(named.group(1)), int(named.group(2))
        wrong = (frame["n"].to_numpy() != n) | (frame["N"].to_numpy() != agents)
        if wrong.any():
            row = int(np.flatnonzero(wrong)[0])
            _refuse(path, f"row {row} has n={frame['n'].iloc[row]}, N={frame['N'].iloc[row]}, not its name's")
    if {"map_seed", "repeat"} <= set(frame) and frame.duplicated(["map_seed", "repeat"]).any():
        row = int(np.flatnonzero(frame.duplicated(["map_seed", "repeat"]).to_numpy())[0])
        _refuse(path, f"row {row} repeats map_seed {frame['map_seed'].iloc[row]}, repeat {frame['repeat'].iloc[row]}")
