"""The run's logs: SB3 logger outputs that survive a resume (one CSV appended across the segments of a run, and
TensorBoard), and with `logger=wandb` a Weights & Biases run that gets every row.

SB3's own CSV output truncates its file when opened, so a resumed run would lose its history; this one keeps it,
drops rows past the checkpoint it resumes from (they will be logged again) and a last row a kill cut short, and
widens the header when a new key appears (team metrics only show up once the first episodes end).

W&B is an SB3 logger output (`KVWriter`) beside the CSV and TensorBoard ones, so it gets exactly the rows the other
two get, at the same agent-steps, with no second logging path. The W&B run is named by the run folder and its id
derived from the folder's path, so a resumed segment continues the same W&B run (rows a resume logs again, past its
checkpoint, are steps W&B has seen: it keeps the first). Offline by default (`logger.mode`): the run is written
under `<run>/wandb/` and `wandb sync` uploads it; nothing needs a network.
"""

from __future__ import annotations

import csv
import hashlib
import io
import numbers
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.logger import KVWriter, TensorBoardOutputFormat

from searchrl.atomic import write_atomic
from searchrl.train.schema import LoggerConfig, TrainConfig
from searchrl.world.config import ConfigError

STEP_KEY = "time/total_timesteps"
# SB3 counts these from 0 in every `learn` call: a resumed segment continues them from the checkpoint's row.
CONTINUED_KEYS = ("time/time_elapsed", "time/iterations")


def _whole_rows(text: str) -> csv.DictReader:
    """The log's rows: a last row cut short by a kill is left out."""
    return csv.DictReader(io.StringIO(text[: text.rfind("\n") + 1], newline=""))


def check_log(path: Path, resume_step: int, every: int) -> None:
    """ConfigError naming what is wrong with the log `path` a run resumes at `resume_step` from, before anything is
    rewritten: not UTF-8 text, no step column, steps going back, or a gap wider than `every` agent-steps (one log
    row per `every`: rows lost to a damaged file) up to the checkpoint. A missing log is fine (none yet)."""
    if not path.exists():
        return
    where = f"{path} (the run's log)"
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ConfigError(f"{where} is not UTF-8 text: move it aside to resume with a new log") from None
    reader = _whole_rows(text)
    rows = list(reader)
    if not rows:  # nothing logged yet (the header alone, or an empty file written when the log was opened)
        return
    if STEP_KEY not in (reader.fieldnames or []):
        raise ConfigError(f"{where} has no {STEP_KEY} column: move it aside to resume with a new log")
    steps = [_step(row) for row in rows]
    kept = [s for s in steps if s <= resume_step]
    for before, after in zip([0.0, *kept], [*kept, float(resume_step)], strict=True):
        if after < before or after - before > every:
            raise ConfigError(
                f"{where} jumps from step {before:g} to {after:g} (a row every {every} agent-steps "
                f"up to the checkpoint at {resume_step}): it is damaged; move it aside to resume with "
                "a new log"
            )


def validated_at(path: Path, step: int) -> bool:
    """Whether the log `path` holds a validation row (`val/found_fraction`) at `step`; a last row cut short by a
    kill does not count."""
    if not path.exists():
        return False
    rows = _whole_rows(path.read_text(encoding="utf-8", errors="replace"))
    return any(_step(row) == step and row.get("val/found_fraction") for row in rows)


def log_digest(path: Path, step: int) -> str | None:
    """sha256 of the log's rows before `step` (each row's non-empty values, by column name: a column added later
    leaves earlier rows as they were), None without a log. A checkpoint at `step` records it; the resume from it
    finds the same rows there, or the log is not the one the checkpoint was saved with. Rows at `step` itself are
    left out: the final validation's row is logged after the last checkpoint."""
    if not path.exists():
        return None
    digest = hashlib.sha256()
    for row in _whole_rows(path.read_text(encoding="utf-8", errors="replace")):
        if _step(row) < step:
            digest.update(repr(sorted((k, v) for k, v in row.items() if k and v)).encode())
    return digest.hexdigest()[:16]


NO_ROWS = hashlib.sha256().hexdigest()[:16]  # `log_digest` of a log with no row before the checkpoint's step


def clock_offsets(path: Path, resume_step: int) -> dict[str, float]:
    """CONTINUED_KEYS' values in the log's last row at or before `resume_step` (0 when there is none)."""
    offsets = dict.fromkeys(CONTINUED_KEYS, 0.0)
    if path.exists():
        for row in csv.DictReader(io.StringIO(path.read_text(encoding="utf-8"), newline="")):
            if _step(row) <= resume_step:
                for key in CONTINUED_KEYS:
                    if row.get(key):
                        offsets[key] = float(row[key])
    return offsets


class ContinuedClock(KVWriter):
    """Passes every row to `writer` with CONTINUED_KEYS advanced by `offsets`: a resumed segment's wall time and
    iterations continue the run's instead of starting again at 1."""

    def __init__(self, writer: KVWriter, offsets: dict[str, float]) -> None:
        self.writer, self.offsets = writer, offsets

    def write(self, key_values: dict[str, Any], key_excluded: dict[str, Any], step: int = 0) -> None:
        shifted = {k: v + self.offsets[k] if k in self.offsets and v is not None else v for k, v in key_values.items()}
        self.writer.write(shifted, key_excluded, step)

    def close(self) -> None:
        self.writer.close()


def _step(row: dict[str, str | None]) -> float:
    """The row's agent-step count; a row without one sorts before every checkpoint."""
    try:
        return float(row.get(STEP_KEY) or 0)
    except ValueError:
        return 0.0


class AppendingCSV(KVWriter):
    def __init__(self, path: str | Path, resume_step: int | None = None) -> None:
        self.path = Path(path)
        self.columns: list[str] = []
        self.rows: list[dict[str, str]] = []
        if self.path.exists():
            text = self.path.read_text()
            if not text.endswith("\n"):  # a row cut short by a kill or a crash: drop it, it is logged again
                text = text[: text.rfind("\n") + 1]
            reader = csv.DictReader(io.StringIO(text, newline=""))
            self.columns = list(reader.fieldnames or [])
            self.rows = [r for r in reader if resume_step is None or _step(r) <= resume_step]
        self._rewrite()

    def write(self, key_values: dict[str, Any], key_excluded: dict[str, Any], step: int = 0) -> None:
        # numbers and text only, and nothing the caller kept from the CSV (TensorBoard's hyperparameters)
        row = {
            k: ("" if v is None else str(v))
            for k, v in key_values.items()
            if (v is None or isinstance(v, (str, int, float, np.number))) and "csv" not in (key_excluded.get(k) or ())
        }
        if not row:
            return
        new = [k for k in row if k not in self.columns]
        self.rows.append(row)
        if new:
            self.columns += sorted(new)
            self._rewrite()
        else:
            with open(self.path, "a", newline="") as f:
                csv.DictWriter(f, self.columns, restval="").writerow(row)

    def _rewrite(self) -> None:
        def write(tmp: Path) -> None:
            with open(tmp, "w", newline="") as f:
                writer = csv.DictWriter(f, self.columns, restval="")
                writer.writeheader()
                writer.writerows(self.rows)

        write_atomic(self.path, write)

    def close(self) -> None:
        pass


class ResumableTensorBoard(TensorBoardOutputFormat):
    """SB3's TensorBoard output; on resume, events logged past the checkpoint by the killed segment are purged
    (`purge_step`), so TensorBoard shows each step once, as the CSV does."""

    def __init__(self, folder: str, purge_step: int | None = None) -> None:
        super().__init__(folder)
        if purge_step is not None:
            from torch.utils.tensorboard import SummaryWriter

            self.writer.close()
            self.writer = SummaryWriter(log_dir=folder, purge_step=purge_step)


MODES = ("offline", "online")


def check_logger(logger: LoggerConfig) -> None:
    """ConfigError in one line for a logger that cannot run: an unknown name or mode, or wandb not installed."""
    if logger.name not in ("default", "wandb"):
        raise ConfigError(f"logger={logger.name!r} is not allowed: default or wandb")
    if logger.name == "wandb":
        if logger.mode not in MODES:
            raise ConfigError(f"logger.mode={logger.mode!r} is not allowed: one of {', '.join(MODES)}")
        try:
            import wandb  # noqa: F401
        except ImportError:
            raise ConfigError("logger=wandb needs the wandb package: pip install -e '.[track]'") from None


class WandbOutput(KVWriter):
    """SB3 logger output to one W&B run: numbers only (W&B's step is the row's agent-step)."""

    def __init__(self, run: Any) -> None:
        self.run = run

    def write(self, key_values: dict[str, Any], key_excluded: dict[str, Any], step: int = 0) -> None:
        values = {
            key: float(value)
            for key, value in key_values.items()
            if isinstance(value, numbers.Number) and not isinstance(value, bool)
        }
        if values:
            self.run.log(values, step=int(step))

    def close(self) -> None:
        self.run.finish()


def start_wandb(cfg: TrainConfig, run_dir: Path) -> WandbOutput:
    """The W&B run of `run_dir` (started, or continued where a segment of it ran before), its config the run's."""
    import wandb

    run_id = hashlib.sha256(str(run_dir.resolve()).encode()).hexdigest()[:16]
    run = wandb.init(
        project=cfg.logger.project,
        entity=cfg.logger.entity,
        group=cfg.logger.group,
        mode=cfg.logger.mode,
        dir=str(run_dir),
        name=run_dir.name,
        id=run_id,
        resume="allow",
        config=asdict(cfg),
    )
    return WandbOutput(run)
