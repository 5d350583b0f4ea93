"""Loading evaluation results into one tidy frame."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from searchrl.evaluate.grid import CELL_FILE_RE
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import PAPER


def cell_files(out_dir: str | Path) -> list[Path]:
    """The finished cells of an evaluation folder, `<out_dir>/cells/<cell>.parquet`, sorted. Only names a cell can
    have count: a writer's hidden temporary (complete or not) or any other file there is never read."""
    return sorted(p for p in Path(out_dir).glob("cells/*.parquet") if CELL_FILE_RE.fullmatch(p.name))


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


def load(*out_dirs: str | Path) -> pd.DataFrame:
    """Every episode row of the given evaluation directories (`<dir>/cells/<cell>.parquet`), one frame."""
    frames = []
    for d in out_dirs:
        for f in cell_files(d):
            try:
                frame = pd.read_parquet(f)
            except Exception as err:  # pyarrow's errors for a damaged file have no common base but Exception
                raise ValueError(f"{f} cannot be read as a cell's results ({type(err).__name__}); remove it and "
                                 "rerun the evaluation into its folder to write it again") from None  # fmt: skip
            if "world" not in frame:
                frame.insert(2, "world", world_of(d))
            if "scenario" not in frame:  # cells made before scenarios existed ran the paper's
                frame.insert(3, "scenario", PAPER.label)
            frames.append(frame)
    if not frames:
        raise FileNotFoundError(f"no cells/*.parquet under {[str(d) for d in out_dirs]}")
    return pd.concat(frames, ignore_index=True)
