"""SB3 logger outputs that survive a resume: one CSV appended across the segments of a run, and TensorBoard.

SB3's own CSV output truncates its file when opened, so a resumed run would lose its history; this one keeps it,
drops rows past the checkpoint it resumes from (they will be logged again), and widens the header when a new
key appears (team metrics only show up once the first episodes end).
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

from stable_baselines3.common.logger import KVWriter, TensorBoardOutputFormat

STEP_KEY = "time/total_timesteps"


class AppendingCSV(KVWriter):
    def __init__(self, path: str | Path, resume_step: int | None = None) -> None:
        self.path = Path(path)
        self.columns: list[str] = []
        self.rows: list[dict[str, str]] = []
        if self.path.exists():
            with open(self.path, newline="") as f:
                reader = csv.DictReader(f)
                self.columns = list(reader.fieldnames or [])
                self.rows = [r for r in reader if resume_step is None or float(r.get(STEP_KEY) or 0) <= resume_step]
        self._rewrite()

    def write(self, key_values: dict[str, Any], key_excluded: dict[str, Any], step: int = 0) -> None:
        row = {k: ("" if v is None else str(v)) for k, v in key_values.items() if not isinstance(v, (dict, list))}
        new = [k for k in row if k not in self.columns]
        self.rows.append(row)
        if new:
            self.columns += sorted(new)
            self._rewrite()
        else:
            with open(self.path, "a", newline="") as f:
                csv.DictWriter(f, self.columns, restval="").writerow(row)

    def _rewrite(self) -> None:
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        with open(tmp, "w", newline="") as f:
            writer = csv.DictWriter(f, self.columns, restval="")
            writer.writeheader()
            writer.writerows(self.rows)
        tmp.replace(self.path)

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
