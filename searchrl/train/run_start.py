"""How a training run starts: its folder checked and cleared, its model (fresh, from `init=` weights, or resumed
from its newest checkpoint), the teacher's clone before RL, and its logs continued across resumed segments."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import VecEnv

from searchrl.atomic import check_writable, remove_temporaries, write_text_atomic
from searchrl.policies.checkpoint import save_model
from searchrl.threads import use_threads
from searchrl.train.build import init_weights, make_algorithm
from searchrl.train.callbacks import checkpoints
from searchrl.train.command_line import fail
from searchrl.train.csv_log import AppendingCSV, ContinuedClock, ResumableTensorBoard, clock_offsets
from searchrl.train.imitation import clone, collect
from searchrl.train.plan import Plan
from searchrl.train.run_record import config_record, load_newest_checkpoint, run_identity, set_aside_logs
from searchrl.train.schema import TrainConfig
from searchrl.train.wandb_log import start_wandb


def prepare_folder(cfg: TrainConfig, run_dir: Path, resuming: bool) -> None:
    """Refuse a folder that holds another run (or a finished one with nothing to resume from), clear what a killed
    writer left, and set torch's and numba's threads as the run records them."""
    if not resuming and ((run_dir / "config.yaml").exists() or checkpoints(run_dir / "checkpoints")):
        fail(f"{run_dir} already holds a run: continue it with resume={run_dir}, or train into another folder")
    if resuming and not checkpoints(run_dir / "checkpoints") and (run_dir / "model.zip").exists():
        fail(
            f"resume={str(run_dir)!r} is a finished run with no checkpoints/ left (a shipped folder): start a new "
            f"run from its weights with init={run_dir / 'model.zip'}"
        )
    for folder in (run_dir, run_dir / "checkpoints"):  # a folder made read-only: said now, not after a rollout
        try:
            check_writable(folder, "resume" if resuming else "hydra.run.dir", folder=True)
        except ValueError as err:
            fail(str(err))
    for folder in (run_dir, run_dir / "checkpoints"):  # left by a killed writer; we hold the folder's lock
        remove_temporaries(folder)
    use_threads(cfg.threads, network_on_cpu=cfg.device == "cpu")  # torch's and the world's (numba's)


def start_model(plan: Plan, run_dir: Path, env: VecEnv, resuming: bool) -> tuple[BaseAlgorithm, bool]:
    """(the algorithm, whether it resumes): the newest readable checkpoint with its step count and optimiser state,
    or a fresh one (from init= weights if given), also for a resume of a run killed before its first checkpoint."""
    cfg = plan.settings
    if resuming:
        model, checkpoint = load_newest_checkpoint(plan, run_dir, env)
        if model is not None:
            start = model.num_timesteps
            if cfg.total_timesteps < start:
                fail(
                    f"total_timesteps={cfg.total_timesteps} is not allowed: {run_dir} has trained {start} "
                    f"agent-steps already ({checkpoint.name}); give total_timesteps >= {start}"
                )
            model.set_random_seed((cfg.seed + start) % 2**32)  # new scenarios, not a replay of the first
            print(f"resuming {run_dir} from {checkpoint.name} at {start} agent-steps", file=sys.stderr)
            return model, True
        aside = set_aside_logs(run_dir)
        print(
            f"{run_dir} has no checkpoint yet: starting it again from step 0"
            + (f" (the killed attempt's logs moved to {aside})" if aside else ""),
            file=sys.stderr,
        )
    model = make_algorithm(plan, env)
    if cfg.init is not None:
        try:
            fresh = init_weights(model, cfg.init, plan.record())
        except ValueError as err:
            fail(str(err))
        print(f"policy weights from {cfg.init}" + (f"; fresh: {', '.join(fresh)}" if fresh else ""), file=sys.stderr)
    return model, False


def record_config(plan: Plan, run_dir: Path) -> None:
    """The run's record (`config_record`), written once the run has started well: a resume writes back what it
    changed (say total_timesteps) but never what it resumes from."""
    write_text_atomic(run_dir / "config.yaml", OmegaConf.to_yaml(config_record(plan.settings)))


def warm_start(plan: Plan, model: BaseAlgorithm, run_dir: Path) -> None:
    """Clone the teacher into the fresh policy (imitation.py); imitation.csv records each epoch, imitation.zip the
    clone before RL, and checkpoints/step_0.zip too, so a kill before the first RL checkpoint resumes from it."""
    im, seed = plan.settings.imitation, plan.settings.seed
    demos = collect(
        list(plan.groups),
        str(plan.teacher),
        im.episodes,
        plan.settings.algo.gamma,
        seed,
        plan.teacher_args,
        plan.scenario,
    )
    print(
        f"imitation: {len(demos)} sequences of {plan.teacher}, found fraction {demos.found_fraction:.3f}",
        file=sys.stderr,
    )
    rows: list[dict[str, float]] = []

    def record(row: dict[str, float]) -> None:
        rows.append({**row, "teacher_found_fraction": demos.found_fraction})
        rows[-1]["epoch"] = len(rows)
        print(
            f"imitation epoch {len(rows)} ({row['phase']}): accuracy {row['accuracy']:.3f}, "
            f"value loss {row['value_loss']:.2f}",
            file=sys.stderr,
        )
        write_text_atomic(run_dir / "imitation.csv", pd.DataFrame(rows).to_csv(index=False))

    fit = (im.epochs, im.value_epochs, im.batch_sequences, im.learning_rate)
    clone(model.policy, demos, *fit, seed, on_epoch=record, lr_schedule=im.lr_schedule)
    save_model(model, run_dir / "imitation.zip", run_identity(plan.settings))  # the clone before RL, to evaluate
    save_model(model, run_dir / "checkpoints" / "step_0.zip", run_identity(plan.settings))


def set_logs(model: BaseAlgorithm, run_dir: Path, resume_step: int | None, cfg: TrainConfig) -> None:
    """One CSV across resumed segments (rows past the checkpoint dropped), plus TensorBoard, plus a W&B run with
    `logger=wandb`; a resumed segment's elapsed time and iterations continue the run's."""
    offsets = clock_offsets(run_dir / "progress.csv", resume_step) if resume_step is not None else {}
    csv_writer = AppendingCSV(run_dir / "progress.csv", resume_step=resume_step)
    purge = None if resume_step is None else resume_step + 1
    writers = [csv_writer, ResumableTensorBoard(str(run_dir / "tensorboard"), purge)]
    if cfg.logger.name == "wandb":
        writers.append(start_wandb(cfg, run_dir))
    model.set_logger(Logger(str(run_dir), [ContinuedClock(w, offsets) for w in writers] if offsets else writers))
