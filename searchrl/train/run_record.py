"""What a run's files say of themselves (its config record, the identity every model it saves carries), and the
resume that reads them: the newest checkpoint that is this run's, or a finished run left untouched.

A run folder is trusted by what its files hold, not by their names. Each model.zip, imitation.zip and
`checkpoints/step_<n>.zip` a run writes holds `searchrl.json` (searchrl/policies/checkpoint.py): the step it was
saved at and the run's settings as `config.yaml` records them, less those a resume may change (RESUME_OVERRIDES).
A resume checks the checkpoint it would continue from against both the file's name and the run's config.yaml, and
refuses, in one line naming both sides, a checkpoint of another run (another model, seed or network: a file copied
in under a step name) or a config.yaml edited since the checkpoint was saved.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecEnv

from searchrl.policies.checkpoint import saved_identity, saved_step
from searchrl.train.build import load_algorithm
from searchrl.train.callbacks import checkpoints
from searchrl.train.command_line import fail
from searchrl.train.csv_log import log_digest
from searchrl.train.plan import Plan
from searchrl.train.schema import RESUME_OVERRIDES, TrainConfig
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


def run_identity(settings: TrainConfig) -> dict[str, Any]:
    """The settings that make a run the run it is: its record less what a resume may change."""
    return {k: v for k, v in config_record(settings).items() if k not in (*RESUME_OVERRIDES, "resume", "hydra")}


def _leaves(node: Any, prefix: str = "") -> dict[str, Any]:
    """{dotted key: value} of a nested mapping (lists are values)."""
    if not isinstance(node, dict):
        return {prefix: node}
    out: dict[str, Any] = {}
    for key, value in node.items():
        out |= _leaves(value, f"{prefix}.{key}" if prefix else str(key))
    return out


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
    theirs, ours = _leaves(identity.get("run", {})), _leaves(run_identity(settings))
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
    that step differ from those the checkpoint's digest covers (`log_digest`). A log the checkpoint saw none of, or
    a missing one, is not compared."""
    identity = saved_identity(checkpoint) or {}
    log = log_digest(checkpoint.parent.parent / "progress.csv", step)
    if identity.get("log") is None or log is None or log == identity["log"]:
        return None
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


def load_newest_checkpoint(plan: Plan, run_dir: Path, env: VecEnv) -> tuple[BaseAlgorithm | None, Path | None]:
    """The newest checkpoint of the run that loads, with its step count and optimiser state. One that cannot be
    read (truncated by a full disk, a broken copy) is set aside as `<name>.unreadable`, said so, and the one
    before it is tried. (None, None) if the run has none: it was killed before its first checkpoint."""
    found = sorted(checkpoints(run_dir / "checkpoints"), reverse=True)
    if not found:
        return None, None
    for step, path in found:
        try:
            problem = foreign_checkpoint(path, step, plan.settings)  # a whole file of another run is not set aside
            if problem:
                fail(f"resume={plan.settings.resume!r}: checkpoints/{path.name} {problem}; nothing was changed")
            return load_algorithm(plan, str(path), env), path
        except OSError as err:  # cannot be read now (permission, I/O): maybe whole, so nothing is set aside
            fail(
                f"resume={plan.settings.resume!r}: {path.name} cannot be read now ({type(err).__name__}: "
                f"{err.strerror or err}); nothing was renamed: restore access and resume again"
            )
        except ValueError as err:
            aside = path.with_name(f"{path.name}.unreadable")
            path.rename(aside)
            print(f"warning: {err}; set aside as {aside.name}, trying the checkpoint before it", file=sys.stderr)
    fail(f"resume={plan.settings.resume!r}: no checkpoint under checkpoints/ can be read (set aside as *.unreadable)")
