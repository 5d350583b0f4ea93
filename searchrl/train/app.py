"""The training app behind `python -m searchrl.train` (searchrl/train/__main__.py): `train` runs one run, `main` is
its Hydra task function.

Trains one shared policy for all agents (parameter sharing) and writes under the run directory: the resolved
`config.yaml`, `progress.csv` and TensorBoard logs (team metrics, losses, validation), `checkpoints/`, and at the
end `model.zip` and `score.json` (the run's score, run_record.py, which `main` returns to Hydra's sweepers), every file
written atomically. `resume=<run dir>` continues a killed run from its newest readable checkpoint with step count
and optimiser state intact; SIGTERM or SIGINT stops it with a checkpoint (exit 143, 130). The run folder is locked
while in use (docs/files.md).

A multirun started again into its own folder (`hydra.sweep.dir`) continues it (`continued_job`): each job whose
folder holds a run of the same settings is not trained again if that run finished (its score is returned, as
Hydra's sweepers need), and is resumed from its newest checkpoint if it was killed; a folder holding a run of other
settings is refused (the job fails, the others run: searchrl/multirun.py). What `resume=` may change
(RESUME_OVERRIDES, say a larger `total_timesteps`) may differ; nothing else may.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList

from searchrl.atomic import hold, storage_message, write_text_atomic
from searchrl.multirun import JobFailed, Stopped, in_sweep, refuse
from searchrl.policies.checkpoint import save_model
from searchrl.shared_schema import CONF_DIR, dotted_leaves, override_keys
from searchrl.train.build import make_vec_env, prepare_folder, set_logs, start_model, warm_start
from searchrl.train.callbacks import (
    AtomicCheckpointCallback,
    HParamsCallback,
    Preemption,
    TeamMetricsCallback,
    ValidationCallback,
    run_hparams,
)
from searchrl.train.logs import check_log, validated_at
from searchrl.train.plan import Plan, make_plan
from searchrl.train.run_record import (
    is_finished,
    other_log,
    read_score,
    record_config,
    run_identity,
    stored_score,
    write_score,
)
from searchrl.train.schema import RESUME_OVERRIDES, register_configs, saved_run
from searchrl.world.config import ConfigError, in_context
from searchrl.world.scenario import Scenario

register_configs()


def resolve_run(cfg: DictConfig, output_dir: Path, overrides: list[str]) -> tuple[DictConfig, Path, bool]:
    """(config, run dir, whether it resumes).

    A resumed run keeps its saved config; only RESUME_OVERRIDES may be changed on the command line (say
    `total_timesteps=` to train longer).
    """
    if cfg.resume is None:
        return cfg, output_dir, False
    run_dir = Path(cfg.resume)
    if not (run_dir / "config.yaml").is_file():
        refuse(f"resume={cfg.resume!r} is not a run directory: it has no config.yaml")
    keys = override_keys(overrides)
    other = [k for k in keys if k not in (*RESUME_OVERRIDES, "resume") and not k.startswith("hydra")]
    if other:
        refuse(f"resume keeps the run's saved config; {other} cannot change (allowed: {', '.join(RESUME_OVERRIDES)})")
    # Merged into the schema: a run saved by an older version gains new fields' defaults, and types are checked.
    with in_context(f"resume={cfg.resume!r}"):
        saved = saved_run(run_dir / "config.yaml")
    saved.resume = cfg.resume
    for key in keys:
        if key in RESUME_OVERRIDES:
            saved[key] = cfg[key]
    return saved, run_dir, True


def train(
    cfg: DictConfig, output_dir: Path, overrides: list[str] | None = None, started: Callable[[], None] | None = None
) -> Path:
    """Run (or resume) one training run; returns the path of the final model.zip. Every setting is checked before
    any file is written (`make_plan`), and the run folder is locked for the whole run (a second resume of it is
    refused). The run, top to bottom: the folder, the env, the algorithm (fresh or from the newest checkpoint), the
    config record (then `started()`: Hydra's record, `hydra_record`), the clone, the logs, the callbacks, RL, the
    final model and score."""
    cfg, run_dir, resuming = resolve_run(cfg, Path(output_dir), overrides or [])
    plan = make_plan(cfg, [] if resuming else overrides or [])  # a refusal (ConfigError) before any file
    for note in plan.notes:
        print(f"note: {note}", file=sys.stderr)
    try:
        with hold(run_dir / ".lock", f"run folder {str(run_dir)!r}"):
            return _train_locked(plan, run_dir, resuming, started)  # FolderBusy: a refusal
    except OSError as err:  # a full disk mid-run: the last checkpoint stands, resume once there is space
        message = storage_message(err)
        if message is None:
            raise
        refuse(f"{message}; the run resumes from its last checkpoint with resume={run_dir}")


def _train_locked(plan: Plan, run_dir: Path, resuming: bool, started: Callable[[], None] | None) -> Path:
    cfg = plan.settings
    prepare_folder(cfg, run_dir, resuming)
    env = make_vec_env(plan)
    model, resuming = start_model(plan, run_dir, env, resuming)
    start_step = model.num_timesteps if resuming else 0
    if resuming and is_finished(run_dir, start_step, cfg.total_timesteps):
        env.close()
        try:
            stored_score(run_dir)
            print(
                f"{run_dir} has trained its {start_step} agent-steps and saved model.zip: nothing to do, no file "
                "changed",
                file=sys.stderr,
            )
        except ValueError as err:  # lost or damaged, or another run's: the score of its own log
            score_again(run_dir, cfg.validation.score_last, err)
            print(f"{run_dir} has trained its {start_step} agent-steps and saved model.zip", file=sys.stderr)
        return run_dir / "model.zip"
    if resuming:  # a damaged log is refused before anything is rewritten
        with in_context(f"resume={cfg.resume!r}"):
            check_log(run_dir / "progress.csv", start_step, plan.rollout * cfg.log_interval)
        problem = other_log(run_dir / "checkpoints" / f"step_{start_step}.zip", start_step)
        if problem:
            refuse(f"resume={cfg.resume!r}: {problem}; nothing was changed")
    record_config(plan.settings, run_dir)
    if started is not None:
        started()
    if not resuming and plan.clones:
        warm_start(plan, model, run_dir)
    # A resume with nothing left to train whose final validation row was lost (a kill while it was written) logs
    # it again: the same weights on the same worlds give the same row, so the score is the run's own.
    validate_final = not resuming or not validated_at(run_dir / "progress.csv", start_step)
    if resuming and validate_final and start_step >= cfg.total_timesteps:
        print(f"note: the final validation at step {start_step} is missing from its log: run again", file=sys.stderr)
    set_logs(model, run_dir, start_step if resuming else None, cfg)
    preemption = Preemption()
    validation = ValidationCallback(
        plan.world,
        plan.scenario,
        cfg.validation.every,
        cfg.validation.n_worlds,
        cfg.validation.seed,
        cfg.validation.deterministic,
        at_start=(plan.clones or cfg.init is not None) and not resuming,
        preemption=preemption,
    )
    callbacks: list[BaseCallback] = [
        HParamsCallback(run_hparams(cfg, plan.scenario.label)),
        TeamMetricsCallback(),
        AtomicCheckpointCallback(
            run_dir / "checkpoints", cfg.checkpoint_every, cfg.keep_checkpoints, preemption, run_identity(cfg)
        ),
        validation,
    ]
    with preemption:
        learn(plan, model, callbacks, validation, resuming, validate_final)
    if preemption.stopped:
        env.close()
        name = signal.Signals(preemption.signal).name
        print(
            f"stopped by {name} at {model.num_timesteps} agent-steps (checkpoints/step_{model.num_timesteps}.zip); "
            f"continue with resume={run_dir}",
            file=sys.stderr,
        )
        raise Stopped(128 + preemption.signal)  # 143 for SIGTERM, 130 for SIGINT, as a shell reports them
    final = save_model(model, run_dir / "model.zip", run_identity(cfg))
    score = write_score(run_dir, cfg.validation.score_last)
    model.logger.close()  # the W&B run finishes here; the CSV and TensorBoard files are complete
    print(
        f"trained {model.num_timesteps} agent-steps; model: {final}; score {score['score']:.4f} (mean found "
        f"fraction of the last {score['validations']} validations)",
        file=sys.stderr,
    )
    env.close()
    return final


def score_again(run_dir: Path, score_last: int, why: ValueError) -> dict[str, object]:
    """Write a finished run's score.json again from its progress.csv, the mean of its last `score_last`
    validations (`why`: what was wrong with it), saying so; refused in one line when the log cannot be read
    either."""
    with in_context(f"{run_dir / 'score.json'} cannot be written again"):
        score = write_score(run_dir, score_last)
    print(f"score.json written again from {run_dir / 'progress.csv'} ({str(why).split(';')[0]})", file=sys.stderr)
    return score


def learn(
    plan: Plan,
    model: BaseAlgorithm,
    callbacks: list[BaseCallback],
    validation: ValidationCallback,
    resuming: bool,
    validate_final: bool = True,
) -> None:
    """RL up to total_timesteps; a run without RL (total_timesteps=0, a clone only), or a resumed one with none left
    whose final validation is not in its log (`validate_final`), is validated once for its score."""
    cfg = plan.settings
    remaining = cfg.total_timesteps - model.num_timesteps
    if remaining > 0:
        model.learn(
            total_timesteps=remaining,
            callback=CallbackList(callbacks),
            log_interval=cfg.log_interval,
            reset_num_timesteps=not resuming,
            progress_bar=cfg.progress_bar,
        )
    elif validate_final:
        validation.init_callback(model)
        validation.num_timesteps = model.num_timesteps  # the row's step: the final model's
        validation.on_training_end()


@hydra.main(version_base="1.3", config_path=str(CONF_DIR), config_name="train")
def main(cfg: DictConfig) -> float:
    """Train, and return the run's score (run_record.py) for Hydra sweepers: `-m hydra/sweeper=optuna` maximises it."""
    hydra_cfg, task_cfg = HydraConfig.get(), cfg
    run_dir, overrides = Path(hydra_cfg.runtime.output_dir), list(hydra_cfg.overrides.task)
    if hydra_cfg.mode == RunMode.MULTIRUN:  # a sweep started again into its folder continues it
        cfg, overrides, finished = in_sweep(continued_job, cfg, run_dir, overrides)
        if finished:
            try:
                score = float(stored_score(run_dir)["score"])
                print(f"{run_dir} holds this job's finished run: not trained again", file=sys.stderr)
            except ValueError as err:  # its score.json damaged or another run's: written again from its own log
                score = float(in_sweep(score_again, run_dir, cfg.validation.score_last, err)["score"])
                print(f"{run_dir} holds this job's finished run: not trained again", file=sys.stderr)
            return score
    try:
        final = in_sweep(train, cfg, run_dir, overrides, hydra_record(task_cfg))
    except (SystemExit, JobFailed):
        remove_hydra_traces(run_dir, hydra_cfg)
        raise
    return read_score(final.parent)


def remove_hydra_traces(output_dir: Path, hydra_cfg: DictConfig) -> None:
    """After a refusal, the folder Hydra made for this job before the app ran (its empty log in it; a resume's
    `resumed/<date>/`, a sweep's job folder) is removed, so a refused command leaves no folder behind. A folder the
    command named (`hydra.run.dir=`) or one holding anything else is left as it is."""
    named = hydra_cfg.mode != RunMode.MULTIRUN and any(
        str(o).startswith("hydra.run.dir=") for o in hydra_cfg.overrides.hydra
    )
    if named or not output_dir.is_dir():
        return
    log = output_dir / f"{hydra_cfg.job.name}.log"
    if {p.name for p in output_dir.iterdir()} <= {log.name} and (not log.exists() or log.stat().st_size == 0):
        log.unlink(missing_ok=True)
        output_dir.rmdir()
        if output_dir.parent.name == "resumed" and not any(output_dir.parent.iterdir()):
            output_dir.parent.rmdir()


def hydra_record(cfg: DictConfig) -> Callable[[], None]:
    """What Hydra's `output_subdir` would write into the job's folder before the app runs (`.hydra/config.yaml`,
    `hydra.yaml`, `overrides.yaml`), written once the run's checks pass (conf/train.yaml sets it to null)."""
    hydra_cfg = HydraConfig.get()

    def write() -> None:
        folder = Path(hydra_cfg.runtime.output_dir) / ".hydra"
        write_text_atomic(folder / "config.yaml", OmegaConf.to_yaml(cfg))
        write_text_atomic(folder / "hydra.yaml", OmegaConf.to_yaml(OmegaConf.create({"hydra": hydra_cfg})))
        write_text_atomic(folder / "overrides.yaml", OmegaConf.to_yaml(hydra_cfg.overrides.task))

    return write


def _settings(cfg: DictConfig) -> dict[str, Any]:
    """The settings that decide a run, flat, its scenario as a run records it (every part written out)."""
    values = OmegaConf.to_container(cfg, resolve=True)
    values["scenario"] = Scenario.from_dict(values.get("scenario")).to_dict()
    return {
        k: v
        for k, v in dotted_leaves(values, keep_empty=True).items()
        if k.split(".")[0] not in (*RESUME_OVERRIDES, "resume")
    }


def continued_job(cfg: DictConfig, run_dir: Path, overrides: list[str]) -> tuple[DictConfig, list[str], bool]:
    """(config, overrides, finished) of a multirun job whose folder `run_dir` may hold a run already: unchanged
    with no run there; finished True for a run of these settings that reached `total_timesteps` (nothing to
    train); else the config resuming it (`resume=run_dir`) with only the changeable overrides. ConfigError for a
    run of other settings, naming the first that differs."""
    if cfg.get("resume") is not None or not (run_dir / "config.yaml").is_file():
        return cfg, overrides, False
    with in_context(f"{run_dir} holds a run that cannot be continued (move it away)"):
        saved = saved_run(run_dir / "config.yaml")
    before, now = _settings(saved), _settings(cfg)
    differ = sorted(k for k in before.keys() | now.keys() if before.get(k, "<absent>") != now.get(k, "<absent>"))
    if differ:
        key = differ[0]
        raise ConfigError(
            f"{run_dir} holds a run of other settings ({key}: {before.get(key, '<absent>')} there, "
            f"{now.get(key, '<absent>')} now): sweep into another hydra.sweep.dir"
        )
    # model.zip is written once the budget is trained; its score.json is checked by `main` above (`stored_score`)
    if (run_dir / "model.zip").is_file() and saved.total_timesteps == cfg.total_timesteps:
        return cfg, overrides, True
    resumed = cfg.copy()
    resumed.resume = str(run_dir)
    kept = [o for o in overrides if o.lstrip("+~").split("=")[0] in RESUME_OVERRIDES]
    return resumed, kept, False
