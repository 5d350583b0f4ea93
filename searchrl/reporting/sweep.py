"""A Hydra multirun folder of training runs as tables: each job's overrides, score and validation curve, and the
score per setting with a confidence interval over seeds (scipy's bootstrap).

A job is a folder under the sweep with `.hydra/overrides.yaml` (what Hydra writes for each job); its score is
`score.json` (searchrl/train/run_record.py), NaN for a job that did not finish. The *setting* of a job is every override
whose value differs between jobs, `seed` left out: the seeds of one setting are its repeats.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from omegaconf import DictConfig, ListConfig, OmegaConf
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
    """Every job folder of the sweep (one holding .hydra/overrides.yaml or a run's config.yaml), sorted by job number
    where it has one."""
    found = {p.parent.parent for p in Path(sweep_dir).glob("*/.hydra/overrides.yaml")}
    found |= {p.parent for p in Path(sweep_dir).glob("*/config.yaml")}

    def order(job: Path) -> tuple[int, str]:
        head = job.name.split("_", 1)[0]
        return (int(head) if head.isdigit() else math.inf, job.name)  # type: ignore[return-value]

    return sorted(found, key=order)


def load_jobs(sweep_dir: Path) -> pd.DataFrame:
    """One row per job: `job` (folder name), one column per override key (values parsed), `score`,
    `validations` (how many the score averages) and `finished` (score.json present).

    Each job's files are checked before they are used, ValueError in one line naming the file: its overrides must
    be readable and say what its run's config.yaml holds, and its score.json must be the score of its own
    progress.csv (searchrl/train/run_record.py `stored_score`), so a job's files swapped for another's or damaged never
    enter the table."""
    from searchrl.train.run_record import stored_score  # here: the module loads torch, a sweep table needs none

    rows = []
    for job in job_folders(sweep_dir):
        row: dict[str, object] = {"job": job.name}
        for key, value in job_overrides(job).items():
            if not key.startswith(IGNORED_PREFIXES):
                row[key] = value
        finished = (job / "score.json").is_file()
        record = stored_score(job) if finished else {}
        row["score"] = float(record.get("score", math.nan))
        row["validations"] = int(record.get("validations", 0))
        row["finished"] = finished
        rows.append(row)
    if not rows:
        raise FileNotFoundError(f"{sweep_dir} holds no sweep jobs (no */.hydra/overrides.yaml)")
    return pd.DataFrame(rows)


def job_overrides(job: Path) -> dict[str, object]:
    """{key: value} of a job's `.hydra/overrides.yaml`, each checked against its run's config.yaml where the key
    names a value of it (a group choice, `+model=b`, names the group's `name`); ValueError in one line naming the
    file when either cannot be read or they disagree."""
    path, config = job / ".hydra" / "overrides.yaml", job / "config.yaml"
    try:
        items = yaml.safe_load(path.read_text())
        if not isinstance(items, list):
            raise ValueError
        cfg = OmegaConf.load(config) if config.is_file() else None
    except (OSError, UnicodeDecodeError, ValueError, yaml.YAMLError):
        raise ValueError(
            f"{path} (or {config.name} beside it) cannot be read as the job's overrides and config; "
            "a sweep rerun into the folder does not rewrite it: remove the job's folder to train it "
            "again"
        ) from None
    overrides = {}
    for item in items:
        key, _, text = str(item).partition("=")
        key, value = key.lstrip("+~"), _value(text)
        overrides[key] = value
        if cfg is None or key.startswith(IGNORED_PREFIXES):
            continue
        held = OmegaConf.select(cfg, key, default=None)
        held = held.get("name") if isinstance(held, DictConfig) else held
        if held is not None and not isinstance(held, ListConfig) and str(held) != str(value):
            raise ValueError(
                f"{path} says {key}={value} but the job's run holds {key}={held} ({config}): another "
                "job's overrides or another run's folder; restore the job's own or remove it"
            )
    return overrides


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
    result = stats.bootstrap(
        (values,),
        np.mean,
        confidence_level=level,
        n_resamples=9999,
        method="percentile",
        random_state=np.random.default_rng(seed),
    )
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
        rows.append(
            {
                **dict(zip(keys, values, strict=True)),
                "seeds": int(group["finished"].sum()),
                "score": mean,
                "low": low,
                "high": high,
            }
        )
    return pd.DataFrame(rows).sort_values("score", ascending=False, na_position="last").reset_index(drop=True)


def validation_curves(sweep_dir: Path, jobs: pd.DataFrame) -> pd.DataFrame:
    """Tidy (job, step, found_fraction, random_found_fraction) of every job's validations, from its progress.csv
    (rows in log order); the last is the random walk on the same validation worlds."""
    frames = []
    for name in jobs["job"]:
        path = Path(sweep_dir) / name / "progress.csv"
        if not path.is_file() or not path.stat().st_size:
            continue
        try:
            progress = pd.read_csv(path)
        except (UnicodeDecodeError, ValueError) as err:  # pandas' parser errors are ValueErrors
            raise ValueError(f"{path} cannot be read as a run's log ({type(err).__name__})") from None
        if "val/found_fraction" not in progress:
            continue
        random = progress.get("val/random_found_fraction", pd.Series(dtype=float))
        points = progress.assign(random=random)[["time/total_timesteps", "val/found_fraction", "random"]]
        points = points.dropna(subset=["val/found_fraction"])
        points.columns = ["step", "found_fraction", "random_found_fraction"]
        frames.append(points.assign(job=name))
    columns = ["job", "step", "found_fraction", "random_found_fraction"]
    return pd.concat(frames, ignore_index=True)[columns] if frames else pd.DataFrame(columns=columns)
