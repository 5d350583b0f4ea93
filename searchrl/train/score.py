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


def stored_score(run_dir: Path) -> dict[str, object]:
    """`score.json` of `run_dir` once checked against the run's own log: the record `run_score` computes from its
    progress.csv over the validations the file says it averaged. ValueError in one line when the file cannot be
    read, or is not the score of this log (another run's, an edited one, or the log changed since)."""
    path = Path(run_dir) / "score.json"
    try:
        record = json.loads(path.read_text())
        last = int(record["last"])
        recorded = (float(record["score"]), [int(s) for s in record["steps"]])
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError):
        raise ValueError(
            f"{path} cannot be read as a run's score; python -m searchrl.train resume={run_dir} "
            "writes it again from the run's progress.csv"
        ) from None
    try:
        own = run_score(run_dir, last)
    except (UnicodeDecodeError, ValueError) as err:  # pandas' parser errors are ValueErrors
        raise ValueError(
            f"{Path(run_dir) / 'progress.csv'} cannot be read as a run's log ({type(err).__name__})"
        ) from None
    same = recorded[1] == own["steps"] and (
        recorded[0] == own["score"] or (math.isnan(recorded[0]) and math.isnan(own["score"]))
    )
    if not same:
        raise ValueError(
            f"{path} is not the score of {Path(run_dir) / 'progress.csv'} (it says {recorded[0]:.4f} at "
            f"steps {recorded[1]}, the log gives {own['score']:.4f} at {own['steps']}): another run's "
            "file or an edited log; resume the run to write it again"
        )
    return own


def read_score(run_dir: Path) -> float:
    """The score recorded in `run_dir/score.json` (NaN if the run has none: it did not finish)."""
    path = Path(run_dir) / "score.json"
    return float(json.loads(path.read_text())["score"]) if path.is_file() else math.nan
