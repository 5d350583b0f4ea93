"""A Hydra multirun folder of training runs as tables: each job's overrides, score and validation curve, and the
score per setting with a confidence interval over seeds (scipy's bootstrap).

A job is a folder under the sweep with `.hydra/overrides.yaml` (what Hydra writes for each job); its score is
`score.json` (searchrl/train/score.py), NaN for a job that did not finish. The *setting* of a job is every override
whose value differs between jobs, `seed` left out: the seeds of one setting are its repeats.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from scipy import stats

SEED = "seed"
IGNORED_PREFIXES = ("hydra.", "hydra/")  # the launcher's and sweeper's own settings


def _value(text: str) -> object:
    """An override's value as YAML reads it (0.001 a float, null None, [1,2] a list shown as text)."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    return value if isinstance(value, (int, float, str, bool)) or value is None else text


def job_folders(sweep_dir: Path) -> list[Path]:
    """Every job folder of the sweep (one holding .hydra/overrides.yaml), sorted by job number where it has one."""
    found = [p.parent.parent for p in Path(sweep_dir).glob("*/.hydra/overrides.yaml")]

    def order(job: Path) -> tuple[int, str]:
        head = job.name.split("_", 1)[0]
        return (int(head) if head.isdigit() else math.inf, job.name)  # type: ignore[return-value]

    return sorted(found, key=order)


def load_jobs(sweep_dir: Path) -> pd.DataFrame:
    """One row per job: `job` (folder name), one column per override key (values parsed), `score`,
    `validations` (how many the score averages) and `finished` (score.json present)."""
    rows = []
    for job in job_folders(sweep_dir):
        overrides = yaml.safe_load((job / ".hydra" / "overrides.yaml").read_text()) or []
        row: dict[str, object] = {"job": job.name}
        for item in overrides:
            key, _, text = str(item).partition("=")
            key = key.lstrip("+~")
            if not key.startswith(IGNORED_PREFIXES):
                row[key] = _value(text)
        score_file = job / "score.json"
        record = json.loads(score_file.read_text()) if score_file.is_file() else {}
        row["score"] = float(record.get("score", math.nan))
        row["validations"] = int(record.get("validations", 0))
        row["finished"] = score_file.is_file()
        rows.append(row)
    if not rows:
        raise FileNotFoundError(f"{sweep_dir} holds no sweep jobs (no */.hydra/overrides.yaml)")
    return pd.DataFrame(rows)


def setting_keys(jobs: pd.DataFrame) -> list[str]:
    """The overrides that differ between jobs, seed left out, in command-line order."""
    reserved = {"job", "score", "validations", "finished", SEED}
    return [c for c in jobs.columns if c not in reserved and jobs[c].astype(str).nunique() > 1]


def mean_ci(values: np.ndarray, level: float = 0.95, seed: int = 0) -> tuple[float, float, float]:
    """(mean, low, high): a percentile bootstrap interval of the mean (scipy.stats.bootstrap, 9999 resamples);
    NaN bounds with fewer than two values. With 3 seeds it describes those seeds: read it as a spread, not as a
    population interval."""
    values = np.asarray(values, float)
    values = values[~np.isnan(values)]
    if values.size == 0:
        return math.nan, math.nan, math.nan
    if values.size < 2:
        return float(values.mean()), math.nan, math.nan
    if np.ptp(values) == 0:
        return float(values[0]), float(values[0]), float(values[0])
    result = stats.bootstrap((values,), np.mean, confidence_level=level, n_resamples=9999, method="percentile",
                             random_state=np.random.default_rng(seed))  # fmt: skip
    interval = result.confidence_interval
    return float(values.mean()), float(interval.low), float(interval.high)


def score_table(jobs: pd.DataFrame, keys: list[str] | None = None, level: float = 0.95) -> pd.DataFrame:
    """One row per setting (`keys`, default `setting_keys`): seeds finished, mean score, CI low/high; best first."""
    keys = setting_keys(jobs) if keys is None else keys
    groups = jobs.groupby(keys, sort=False, dropna=False) if keys else [((), jobs)]
    rows = []
    for key, group in groups:
        mean, low, high = mean_ci(group["score"].to_numpy(), level)
        values = key if isinstance(key, tuple) else (key,)
        rows.append({**dict(zip(keys, values, strict=True)), "seeds": int(group["finished"].sum()),
                     "score": mean, "low": low, "high": high})  # fmt: skip
    return pd.DataFrame(rows).sort_values("score", ascending=False, na_position="last").reset_index(drop=True)


def validation_curves(sweep_dir: Path, jobs: pd.DataFrame) -> pd.DataFrame:
    """Tidy (job, step, found_fraction, random_found_fraction) of every job's validations, from its progress.csv
    (rows in log order); the last is the random walk on the same validation worlds."""
    frames = []
    for name in jobs["job"]:
        path = Path(sweep_dir) / name / "progress.csv"
        if not path.is_file() or not path.stat().st_size:
            continue
        progress = pd.read_csv(path)
        if "val/found_fraction" not in progress:
            continue
        random = progress.get("val/random_found_fraction", pd.Series(dtype=float))
        points = progress.assign(random=random)[["time/total_timesteps", "val/found_fraction", "random"]]
        points = points.dropna(subset=["val/found_fraction"])
        points.columns = ["step", "found_fraction", "random_found_fraction"]
        frames.append(points.assign(job=name))
    columns = ["job", "step", "found_fraction", "random_found_fraction"]
    return pd.concat(frames, ignore_index=True)[columns] if frames else pd.DataFrame(columns=columns)
