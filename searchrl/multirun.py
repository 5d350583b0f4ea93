"""Refusals and stops as exceptions, and what the apps' entry points make of them: an exit status, or in a multirun
a failed job while the other jobs run, with a summary at the sweep's end and exit status 1.

Below the entry points nothing ends the process: a setting refused before any work raises the library's one
refusal, `ConfigError` (searchrl/world/config.py; its one line for stderr), a run stopped by a signal after its
checkpoint raises `Stopped`. `in_sweep`, called by an app's Hydra task function, prints the refusal's line and
turns either into the process's exit status (`exit_for`: 2, or 143 / 130 after SIGTERM / SIGINT), or inside a
multirun into `JobFailed`: Hydra's launchers go on to the next job after one that raises an Exception and raise the
first failure once the batch is done. `FailedJobs`, a Hydra callback (`hydra.callbacks` of conf/train.yaml and
conf/evaluate.yaml), files each failed job's overrides and error line in the sweep folder and prints them all as
the process ends, after Hydra's report of the first failure (Hydra skips `on_multirun_end` when a job failed): a
file reaches the parent whichever process a launcher ran the job in (joblib's workers, submitit's nodes).
"""

from __future__ import annotations

import atexit
import functools
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NoReturn, TypeVar

from hydra.core.hydra_config import HydraConfig
from hydra.core.utils import JobReturn, JobStatus
from hydra.errors import CompactHydraException
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig
from omegaconf.errors import OmegaConfBaseException

from searchrl.atomic import write_text_atomic
from searchrl.world.config import ConfigError

FAILED = ".failed"  # <sweep dir>/.failed/<job number>.txt: one line per failed job, "overrides<TAB>error"
T = TypeVar("T")


class Stopped(Exception):
    """A run stopped by a signal after writing its checkpoint: exit status `code` (128 + the signal's number)."""

    def __init__(self, code: int) -> None:
        super().__init__(f"stopped with exit status {code}")
        self.code = code


class JobFailed(CompactHydraException):
    """A multirun job that was refused or stopped: Hydra goes on to the next. Compact: when Hydra raises the first
    failure at the batch's end it prints its one line, not a traceback."""


def said_as_refusal(check: Callable[..., T]) -> Callable[..., T]:
    """Decorator for the function that checks a command before any work (a training's plan, an evaluation's, a
    render's setup): a ValueError of a part or an OmegaConf typing error inside it leaves it as a ConfigError of
    its first line, so an app handles one refusal type."""

    @functools.wraps(check)
    def checked(*args: Any, **kwargs: Any) -> T:
        try:
            return check(*args, **kwargs)
        except ConfigError:
            raise
        except (ValueError, OmegaConfBaseException) as err:
            text = str(err).strip()
            raise ConfigError(text.splitlines()[0] if text else type(err).__name__) from None

    return checked


def refuse(message: str) -> NoReturn:
    """Refuse a setting: raise `ConfigError(message)`; an entry point prints `error: <message>` and exits with 2."""
    raise ConfigError(message)


def exit_for(error: ConfigError | Stopped) -> NoReturn:
    """What an entry point makes of a refusal or a stop: the refusal's one line on stderr, the exit status."""
    if isinstance(error, ConfigError):
        print(f"error: {error.message}", file=sys.stderr)
    raise SystemExit(error.code)


@contextmanager
def exits() -> Iterator[None]:
    """`with exits():` around a call an entry point makes: a refusal or a stop ends the process (`exit_for`)."""
    try:
        yield
    except (ConfigError, Stopped) as error:
        exit_for(error)


def in_sweep(task: Callable[..., T], *args: Any) -> T:
    """task(*args) for an app's Hydra task function: a refusal (ConfigError) or a stop ends the process
    (`exit_for`), or in a multirun fails this job only (JobFailed, after the refusal's line), so the sweep goes on
    (an Optuna trial is marked failed, not left running)."""
    try:
        return task(*args)
    except (ConfigError, Stopped) as error:
        if HydraConfig.get().mode != RunMode.MULTIRUN:
            exit_for(error)
        if isinstance(error, ConfigError):
            print(f"error: {error.message}", file=sys.stderr)
        raise JobFailed(str(error)) from None


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
