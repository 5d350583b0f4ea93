"""The run's score: one number a Hydra sweeper can optimise, written beside the run as `score.json`.

The score is the validation found fraction (`val/found_fraction` in `progress.csv`, fixed validation worlds) averaged
over the last `validation.score_last` validations of the run, resumed segments included; the final model is always
among them (the validation callback runs once more when training ends). `score.json` says which validations, at
which agent-steps, were averaged.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd

from searchrl.atomic import write_text_atomic

METRIC = "val/found_fraction"
STEP = "time/total_timesteps"


def run_score(run_dir: Path, last: int) -> dict[str, object]:
    """{"score", "metric", "validations" (how many were averaged), "steps" (their agent-steps), "last"} from
    `run_dir/progress.csv`; score is NaN when the run logged no validation."""
    path = Path(run_dir) / "progress.csv"
    frame = pd.read_csv(path) if path.is_file() and path.stat().st_size else pd.DataFrame()
    points = frame.reindex(columns=[STEP, METRIC]).dropna().tail(last)  # no validation logged: no rows
    score = float(points[METRIC].mean()) if len(points) else math.nan
    return {
        "score": score,
        "metric": METRIC,
        "last": last,
        "validations": len(points),
        "steps": [int(s) for s in points[STEP]],
    }


def write_score(run_dir: Path, last: int) -> dict[str, object]:
    """Compute the run's score, write `score.json` atomically, and return its record."""
    record = run_score(run_dir, last)
    write_text_atomic(Path(run_dir) / "score.json", json.dumps(record, indent=1) + "\n")
    return record


def read_score(run_dir: Path) -> float:
    """The score recorded in `run_dir/score.json` (NaN if the run has none: it did not finish)."""
    path = Path(run_dir) / "score.json"
    return float(json.loads(path.read_text())["score"]) if path.is_file() else math.nan
