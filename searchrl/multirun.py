"""What a multirun does with a refused job: the other jobs run, and the sweep ends with a summary and exit status 1.

Hydra's launchers go on to the next job after one that raises an Exception, and raise the first failure once the
batch is done; a `SystemExit` (an app's one-line refusal, `refuse`) would end the whole sweep at that job instead.
`in_sweep` turns the one into the other inside a multirun. `FailedJobs`, a Hydra callback (`hydra.callbacks` of
conf/train.yaml and conf/evaluate.yaml), files each failed job's overrides and error line in the sweep folder and
prints them all as the process ends, after Hydra's report of the first failure (Hydra skips `on_multirun_end`
when a job failed): a file reaches the parent whichever process a launcher ran the job in (joblib's workers,
submitit's nodes).
"""

from __future__ import annotations

import atexit
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn, TypeVar

from hydra.core.hydra_config import HydraConfig
from hydra.core.utils import JobReturn, JobStatus
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig

from searchrl.atomic import write_text_atomic

FAILED = ".failed"  # <sweep dir>/.failed/<job number>.txt: one line per failed job, "overrides<TAB>error"
T = TypeVar("T")


class Refused(SystemExit):
    """A setting refused before any work: exit status 2, its one line already on stderr."""

    def __init__(self, message: str) -> None:
        super().__init__(2)
        self.message = message


class JobFailed(RuntimeError):
    """A multirun job that stopped with a non-zero exit status (a refusal, a signal): Hydra goes on to the next."""


def refuse(message: str) -> NoReturn:
    """Name the bad value and what is allowed, in one line on stderr, and exit with status 2 (before any work)."""
    print(f"error: {message}", file=sys.stderr)
    raise Refused(message)


def in_sweep(task: Callable[..., T], *args: Any) -> T:
    """task(*args); in a multirun a SystemExit with a non-zero status becomes JobFailed, so the sweep goes on (an
    Optuna trial is marked failed, not left running)."""
    try:
        return task(*args)
    except SystemExit as stop:
        if HydraConfig.get().mode == RunMode.MULTIRUN and stop.code not in (0, None):
            detail = stop.message if isinstance(stop, Refused) else f"stopped with exit status {stop.code}"
            raise JobFailed(detail) from None
        raise


class FailedJobs(Callback):
    """Hydra callback: files each failed job of a multirun and names them all at its end (module docstring)."""

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        folder = Path(config.hydra.sweep.dir) / FAILED
        for old in folder.glob("*.txt"):  # a sweep continued in its folder
            old.unlink(missing_ok=True)
        atexit.register(summarize, folder)

    def on_job_end(self, config: DictConfig, job_return: JobReturn, **kwargs: Any) -> None:
        if config.hydra.mode != RunMode.MULTIRUN or job_return.status != JobStatus.FAILED:
            return
        error = job_return._return_value
        line = str(error).splitlines()[0] if str(error) else type(error).__name__
        overrides = " ".join(job_return.overrides or [])
        folder = Path(config.hydra.sweep.dir) / FAILED
        folder.mkdir(parents=True, exist_ok=True)
        write_text_atomic(folder / f"{config.hydra.job.num}.txt", f"{overrides}\t{line}\n")


def summarize(folder: Path) -> None:
    """Print the failed jobs filed in `folder`, one line each (nothing when none failed)."""
    files = sorted(folder.glob("*.txt"), key=lambda p: int(p.stem))
    if not files:
        return
    print(f"error: {len(files)} job(s) of the multirun failed; the others ran:", file=sys.stderr)
    for path in files:
        overrides, _, line = path.read_text().rstrip("\n").partition("\t")
        print(f"  #{path.stem} [{overrides}]: {line}", file=sys.stderr)
