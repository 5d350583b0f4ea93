"""Loading evaluation results into one tidy frame."""

from __future__ import annotations

from pathlib import Path

import pandas as pd


def load(*out_dirs: str | Path) -> pd.DataFrame:
    """Every episode row of the given evaluation directories (`<dir>/cells/*.parquet`), one frame."""
    files = [f for d in out_dirs for f in sorted(Path(d).glob("cells/*.parquet"))]
    if not files:
        raise FileNotFoundError(f"no cells/*.parquet under {[str(d) for d in out_dirs]}")
    return pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
