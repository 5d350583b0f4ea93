# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Carrying long trainings to the next machine
#
# Carry long trainings from one machine to the next through the repository: each run folder's record and newest
# checkpoint, copied into `runs/lab/<name>/` (tracked by git), where `resume=` continues it on any machine:
#
#     python analysis/carry_runs.py runs/train/research/team_b [RUN ...]      # -> runs/lab/team_b, ...
#     cp -r runs/lab/team_b runs/train/research/                              # on the next machine
#     python -m searchrl.train resume=runs/train/research/team_b threads=1
#
# A run folder keeps, beside its config, log and record (config.yaml, progress.csv, train.log, .hydra/), one
# checkpoint per `checkpoint_every`; a resume needs only the newest (it drops the log's rows past that step itself),
# with its optimiser's moments, so the training goes on as if it had not stopped. The checkpoint is copied without the
# rollout in progress (`_last_obs`, which no load reads: searchrl/policies/checkpoint.py's LEFT_EMPTY); its weights,
# and so their digest, are the same bytes. An older carried checkpoint of the same run is removed, and the copy is
# atomic file by file, so an interrupted carry leaves the previous one whole.

# %%
from __future__ import annotations

import shutil
import sys
from pathlib import Path

from searchrl.atomic import write_atomic
from searchrl.policies.slim import slim_checkpoint

RECORD = ("config.yaml", "progress.csv", "train.log", "score.json")
LAB = Path("runs/lab")


# %%
def newest_checkpoint(run: Path) -> Path:
    """The checkpoint of the most agent-steps in run/checkpoints (step_<n>.zip)."""
    found = sorted((run / "checkpoints").glob("step_*.zip"), key=lambda p: int(p.stem.split("_")[1]))
    if not found:
        raise SystemExit(f"carry_runs: {str(run)!r} holds no checkpoints/step_<n>.zip (expected a training run folder)")
    return found[-1]


# %%
def carry(run: Path, lab: Path = LAB, moments: bool = True) -> Path:
    """Copy `run`'s record and newest checkpoint (without the optimiser's moments unless `moments`) into
    lab/<run's name>; return that folder."""
    if not (run / "config.yaml").is_file():
        raise SystemExit(f"carry_runs: {str(run)!r} has no config.yaml (expected a training run folder)")
    checkpoint = newest_checkpoint(run)
    dest = lab / run.name
    if dest.resolve() == run.resolve():
        raise SystemExit(f"carry_runs: {str(run)!r} is already under {lab}")
    (dest / "checkpoints").mkdir(parents=True, exist_ok=True)
    slim_checkpoint(checkpoint, dest / "checkpoints" / checkpoint.name, keep_moments=moments)  # the rollout dropped
    for name in RECORD:
        if (run / name).is_file():
            write_atomic(dest / name, lambda tmp, src=run / name: shutil.copyfile(src, tmp))
    if (run / ".hydra").is_dir():
        shutil.copytree(run / ".hydra", dest / ".hydra", dirs_exist_ok=True)
    for old in (dest / "checkpoints").glob("step_*.zip"):
        if old.name != checkpoint.name:
            old.unlink()
    return dest


# %%
def main(argv: list[str]) -> int:
    lab, moments = LAB, "--without-moments" not in argv  # a third of the size: for a tree that must stay small
    argv = [arg for arg in argv if arg != "--without-moments"]
    if argv[:1] == ["--to"] and len(argv) > 1:
        lab, argv = Path(argv[1]), argv[2:]
    if not argv or any(arg.startswith("--") for arg in argv):
        print(
            "usage: python analysis/carry_runs.py [--to DIR] [--without-moments] RUN_DIR [RUN_DIR ...]"
            "  (into DIR/<name>, runs/lab by default)",
            file=sys.stderr,
        )
        return 2
    for run in map(Path, argv):
        dest = carry(run, lab, moments)
        size = sum(p.stat().st_size for p in dest.rglob("*") if p.is_file())
        print(f"{run} -> {dest} ({newest_checkpoint(dest).name}, {size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
