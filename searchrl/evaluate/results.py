"""Loading evaluation results into one tidy frame."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from searchrl.evaluate.grid import CELL_FILE_RE


def cell_files(out_dir: str | Path) -> list[Path]:
    """The finished cells of an evaluation folder, `<out_dir>/cells/<cell>.parquet`, sorted. Only names a cell can
    have count: a writer's hidden temporary (complete or not) or any other file there is never read."""
    return sorted(p for p in Path(out_dir).glob("cells/*.parquet") if CELL_FILE_RE.fullmatch(p.name))


def load(*out_dirs: str | Path) -> pd.DataFrame:
    """Every episode row of the given evaluation directories (`<dir>/cells/<cell>.parquet`), one frame."""
    files = [f for d in out_dirs for f in cell_files(d)]
    if not files:
        raise FileNotFoundError(f"no cells/*.parquet under {[str(d) for d in out_dirs]}")
    return pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
