"""What a run's files say of themselves: its config record, the identity every model it saves carries, and its
score; a resume reads them to continue from the newest checkpoint that is this run's (build.py's
`load_newest_checkpoint`), or to leave a finished run untouched.

A run folder is trusted by what its files hold, not by their names. Each model.zip, imitation.zip and
`checkpoints/step_<n>.zip` a run writes holds `searchrl.json` (searchrl/policies/checkpoint.py): the step it was
saved at and the run's settings as `config.yaml` records them, less those a resume may change (RESUME_OVERRIDES).
A resume checks the checkpoint it would continue from against both the file's name and the run's config.yaml, and
refuses, in one line naming both sides, a checkpoint of another run (another model, seed or network: a file copied
in under a step name) or a config.yaml edited since the checkpoint was saved.

The run's score is one number a Hydra sweeper can optimise, written beside the run as `score.json`: the validation
found fraction (`val/found_fraction` in `progress.csv`, fixed validation worlds) averaged over the last
`validation.score_last` validations of the run, resumed segments included; the final model is always among them
(the validation callback runs once more when training ends). `score.json` says which validations, at which
agent-steps, were averaged.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pandas as pd
from omegaconf import OmegaConf

from searchrl.atomic import write_text_atomic
from searchrl.policies.checkpoint import saved_identity, saved_step
from searchrl.shared_schema import dotted_leaves
from searchrl.train.logs import NO_ROWS, log_digest
from searchrl.train.schema import RESUME_OVERRIDES, TrainConfig
from searchrl.world.config import ConfigError
from searchrl.world.scenario import Scenario


def config_record(settings: TrainConfig) -> dict[str, Any]:
    """The run's record as config.yaml holds it: resolved, `resume` cleared, the scenario with every part written
    out (a run made before a part existed drew its default)."""
    record = OmegaConf.structured(settings)
    record.resume = None
    record.scenario = Scenario.from_dict(
        OmegaConf.to_container(record.scenario, resolve=True) if "scenario" in record else None
    ).to_dict()
    return OmegaConf.to_container(record, resolve=True)


def record_config(settings: TrainConfig, run_dir: Path) -> None:
    """The run's record (`config_record`) as `run_dir/config.yaml`, written once the run has started well: a resume
    writes back what it changed (say total_timesteps) but never what it resumes from."""
    write_text_atomic(run_dir / "config.yaml", OmegaConf.to_yaml(config_record(settings)))


def run_identity(settings: TrainConfig) -> dict[str, Any]:
    """The settings that make a run the run it is: its record less what a resume may change."""
    return {k: v for k, v in config_record(settings).items() if k not in (*RESUME_OVERRIDES, "resume", "hydra")}


def foreign_checkpoint(path: Path, step: int, settings: TrainConfig) -> str | None:
    """Why the checkpoint `path`, named for `step`, cannot be this run's (of `settings`), or None: the step
    it was saved at is another, or a setting it records differs from the run's config.yaml. Settings one side lacks
    are not compared (a later version adds settings at their defaults). A file saved
    before models carried an identity is checked by its step alone."""
    saved = saved_step(path)
    if saved != step:
        return f"holds a model saved at step {saved}, not {step} (move it out of checkpoints/ to resume from the last)"
    identity = saved_identity(path)
    if identity is None:
        return None
    if identity.get("step") != step:
        return f"records step {identity.get('step')}, not {step} (move it out of checkpoints/)"
    theirs, ours = dotted_leaves(identity.get("run", {})), dotted_leaves(run_identity(settings))
    differ = sorted(k for k in theirs.keys() & ours.keys() if theirs[k] != ours[k])
    if differ:
        key = differ[0]
        more = f" (and {len(differ) - 1} more settings)" if len(differ) > 1 else ""
        return (
            f"was saved by a run with {key}={theirs[key]!r}, but the run's config.yaml says {key}={ours[key]!r}"
            f"{more}: another run's checkpoint (move it out of checkpoints/), or a config.yaml edited since "
            "(restore it)"
        )
    return None


def other_log(checkpoint: Path, step: int) -> str | None:
    """Why the run's progress.csv is not the log `checkpoint` (at `step`) was saved with, or None: its rows before
    that step differ from those the checkpoint's digest covers (`log_digest`), or it is missing where the
    checkpoint saw rows. A checkpoint saved with no digest is not compared."""
    identity = saved_identity(checkpoint) or {}
    log = log_digest(checkpoint.parent.parent / "progress.csv", step)
    if identity.get("log") is None or log == identity["log"]:
        return None
    if log is None and identity["log"] == NO_ROWS:  # no log, and the checkpoint saw none: nothing is lost
        return None
    if log is None:
        return (
            f"progress.csv is missing, and checkpoints/{checkpoint.name} was saved with its rows before step {step}: "
            "restore it to resume (a new log would start again at iteration 1 without the run's validations)"
        )
    return (
        f"progress.csv is not the log checkpoints/{checkpoint.name} was saved with (its rows before step {step} "
        "differ: another run's log, or an edited one); move it aside to resume with a new log"
    )


def is_finished(run_dir: Path, step: int, total: int) -> bool:
    """Whether the run has trained `total` agent-steps and its model.zip is the model of that step: a resume with
    that budget trains nothing (at most its score.json is written again, from its log)."""
    try:
        return step >= total and saved_step(run_dir / "model.zip") == step
    except (OSError, ValueError):  # no model.zip, or a damaged one: the resume writes it again
        return False


def set_aside_logs(run_dir: Path) -> Path | None:
    """Move the logs of an attempt killed before its first checkpoint (progress.csv, tensorboard/, imitation.csv)
    into `<run>/killed/<k>/`, so the restart from step 0 logs every step once; the folder, or None if none."""
    logs = [run_dir / name for name in ("progress.csv", "tensorboard", "imitation.csv") if (run_dir / name).exists()]
    if not logs:
        return None
    k = 0
    while (run_dir / "killed" / str(k)).exists():
        k += 1
    aside = run_dir / "killed" / str(k)
    aside.mkdir(parents=True)
    for path in logs:
        path.rename(aside / path.name)
    return aside


METRIC = "val/found_fraction"
STEP = "time/total_timesteps"


def run_score(run_dir: Path, last: int) -> dict[str, object]:
    """{"score", "metric", "validations" (how many were averaged), "steps" (their agent-steps), "last"} from
    `run_dir/progress.csv`; score is NaN when the run logged no validation. ConfigError when the log cannot be
    read."""
    path = Path(run_dir) / "progress.csv"
    try:
        frame = pd.read_csv(path) if path.is_file() and path.stat().st_size else pd.DataFrame()
    except ValueError as err:  # pandas' parser errors and UnicodeDecodeError are ValueErrors
        raise ConfigError(f"{path} cannot be read as a run's log ({type(err).__name__})") from None
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
    own = run_score(run_dir, last)
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
