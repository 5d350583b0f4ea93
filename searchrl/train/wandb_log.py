"""`logger=wandb`: every row the run logs (progress.csv's keys) also goes to a Weights & Biases run.

An SB3 logger output (`KVWriter`) beside the CSV and TensorBoard ones, so W&B gets exactly the rows the other two get,
at the same agent-steps, with no second logging path. The W&B run is named by the run folder and its id derived from
the folder's path, so a resumed segment continues the same W&B run (rows a resume logs again, past its checkpoint,
are steps W&B has seen: it keeps the first). Offline by default (`logger.mode`): the run is written under
`<run>/wandb/` and `wandb sync` uploads it; nothing needs a network.
"""

from __future__ import annotations

import hashlib
import numbers
from dataclasses import asdict
from pathlib import Path
from typing import Any

from stable_baselines3.common.logger import KVWriter

from searchrl.train.schema import LoggerConfig, TrainConfig
from searchrl.world.config import ConfigError

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
