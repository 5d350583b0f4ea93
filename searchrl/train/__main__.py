"""`python -m searchrl.train +model=<a|b|c|diagonal> [algo=a2c|ppo] [network=small] [key=value ...]`

Trains one shared policy for all agents (parameter sharing) and writes under the run directory: the resolved
`config.yaml`, `progress.csv` and TensorBoard logs (team metrics, losses, validation), `checkpoints/`, and at the
end `model.zip` and `score.json` (the run's score, score.py, which `main` returns to Hydra's sweepers), every file
written atomically. `resume=<run dir>` continues a killed run from its newest readable checkpoint with step count
and optimiser state intact. The run folder is locked while in use (docs/files.md).
"""

from __future__ import annotations

import copy
import os

# Sleep rather than spin when torch's OpenMP threads wait: with parallel sweeps or any other busy process on the
# cores, spinning threads slowed a tiny run 20x here. Set OMP_WAIT_POLICY yourself to override.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import sys
from pathlib import Path

import hydra
import pandas as pd
import torch
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.utils import get_device
from stable_baselines3.common.vec_env import VecEnv

from searchrl.atomic import FolderBusy, hold, remove_temporaries, write_atomic, write_text_atomic
from searchrl.controllers.policy import retired_kwargs_dropped
from searchrl.train.build import (
    TRAINABLE_MODELS,
    attach_teacher,
    check_config,
    label_env,
    load_algorithm,
    make_algorithm,
    make_vec_env,
    rollout_size,
    scenario_of,
    teacher_args,
    team_groups,
    unused_settings,
    world_config,
)
from searchrl.train.callbacks import (
    AtomicCheckpointCallback,
    TeamMetricsCallback,
    ValidationCallback,
    checkpoints,
)
from searchrl.train.command_line import check_resume_argument, fail, recipe_arguments
from searchrl.train.csv_log import AppendingCSV, ResumableTensorBoard
from searchrl.train.imitation import clone, collect
from searchrl.train.schema import TrainConfig, override_keys, register_configs, saved_config
from searchrl.train.score import read_score, write_score
from searchrl.world.config import ConfigError

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"
register_configs()


def check_model(cfg: DictConfig) -> None:
    models = sorted(p.stem for p in (CONF_DIR / "model").glob("*.yaml"))
    trainable = [m for m in models if m in TRAINABLE_MODELS]
    if cfg.model is None:
        fail(f"choose a model to train with +model=<name>; trainable models: {', '.join(trainable)}")
    if not cfg.model.trainable:
        fail(
            f"model {cfg.model.name!r} is a heuristic controller, not trainable: use "
            f"`python -m searchrl.evaluate controller={cfg.model.name}`; trainable models: {', '.join(trainable)}"
        )


RESUME_OVERRIDES = ("total_timesteps", "threads", "device", "progress_bar", "keep_checkpoints")


def resolve_run(cfg: DictConfig, output_dir: Path, overrides: list[str]) -> tuple[DictConfig, Path, bool]:
    """(config, run dir, whether it resumes).

    A resumed run keeps its saved config; only RESUME_OVERRIDES may be changed on the command line (say
    `total_timesteps=` to train longer).
    """
    if cfg.resume is None:
        return cfg, output_dir, False
    run_dir = Path(cfg.resume)
    if not (run_dir / "config.yaml").is_file():
        fail(f"resume={cfg.resume!r} is not a run directory: it has no config.yaml")
    keys = override_keys(overrides)
    other = [k for k in keys if k not in (*RESUME_OVERRIDES, "resume", "recipe") and not k.startswith("hydra")]
    if other:
        fail(f"resume keeps the run's saved config; {other} cannot change (allowed: {', '.join(RESUME_OVERRIDES)})")
    # Merged into the schema: a run saved by an older version gains new fields' defaults, and types are checked.
    try:
        loaded = saved_config(run_dir / "config.yaml")
        if loaded.get("model") is None or loaded.get("algo") is None:
            raise ValueError("it names no model or algo")
        saved = OmegaConf.merge(OmegaConf.structured(TrainConfig), loaded)
    except Exception as err:  # empty, not YAML, wrong types, unreadable: the run's record is damaged
        detail = str(err).splitlines()[0] if str(err) else type(err).__name__
        fail(f"resume={cfg.resume!r}: its config.yaml does not fit the current schema or cannot be read ({detail})")
    saved.resume = cfg.resume
    for key in keys:
        if key in RESUME_OVERRIDES:
            saved[key] = cfg[key]
    return saved, run_dir, True


def load_newest_checkpoint(cfg: DictConfig, run_dir: Path, env: VecEnv) -> tuple[BaseAlgorithm | None, Path | None]:
    """The newest checkpoint of the run that loads, with its step count and optimiser state. One that cannot be
    read (truncated by a full disk, a broken copy) is set aside as `<name>.unreadable`, said so, and the one
    before it is tried. (None, None) if the run has none: it was killed before its first checkpoint."""
    found = sorted(checkpoints(run_dir / "checkpoints"), reverse=True)
    if not found:
        return None, None
    for _, path in found:
        try:
            return load_algorithm(cfg, str(path), env), path
        except ValueError as err:
            aside = path.with_name(f"{path.name}.unreadable")
            path.rename(aside)
            print(f"warning: {err}; set aside as {aside.name}, trying the checkpoint before it", file=sys.stderr)
    fail(f"resume={cfg.resume!r}: no checkpoint under checkpoints/ can be read (set aside as *.unreadable)")


def init_weights(model: BaseAlgorithm, path: str) -> None:
    """Copy the policy weights of checkpoint `path` into the fresh `model` (its optimiser state is not taken)."""
    try:
        params = type(model).load(path, device="cpu", custom_objects=retired_kwargs_dropped(path)).get_parameters()
        model.set_parameters({"policy": params["policy"]}, exact_match=False, device=model.device)
    except Exception as err:  # a zip of another algorithm, a corrupt file, other shapes: all end here
        lines = str(err).strip().splitlines() or [type(err).__name__]
        more = f" (+{len(lines) - 1} more lines)" if len(lines) > 1 else ""
        fail(f"init={path!r} does not fit this run's policy (algo, network, observation and action spaces must "
             f"match): {lines[0]}{more}")  # fmt: skip
    print(f"policy weights from {path}", file=sys.stderr)


def warm_start(cfg: DictConfig, model: BaseAlgorithm, run_dir: Path) -> None:
    """Clone the teacher into the fresh policy (imitation.py); imitation.csv records each epoch and imitation.zip the
    clone before RL."""
    im, groups, gamma, seed = cfg.imitation, team_groups(cfg), float(cfg.algo.gamma), int(cfg.seed)
    demos = collect(groups, im.teacher, int(im.episodes), gamma, seed, teacher_args(cfg), scenario_of(cfg))
    print(f"imitation: {len(demos)} sequences of {im.teacher}, found fraction {demos.found_fraction:.3f}",
          file=sys.stderr)  # fmt: skip
    rows: list[dict[str, float]] = []

    def record(row: dict[str, float]) -> None:
        rows.append({**row, "teacher_found_fraction": demos.found_fraction})
        rows[-1]["epoch"] = len(rows)
        print(f"imitation epoch {len(rows)} ({row['phase']}): accuracy {row['accuracy']:.3f}, "
              f"value loss {row['value_loss']:.2f}", file=sys.stderr)  # fmt: skip
        write_text_atomic(run_dir / "imitation.csv", pd.DataFrame(rows).to_csv(index=False))

    fit = (int(im.epochs), int(im.value_epochs), int(im.batch_sequences), float(im.learning_rate))
    schedule = str(im.get("lr_schedule", "constant"))
    clone(model.policy, demos, *fit, seed, on_epoch=record, lr_schedule=schedule)
    write_atomic(run_dir / "imitation.zip", lambda tmp: model.save(tmp))  # the clone before RL, to evaluate


def train(cfg: DictConfig, output_dir: Path, overrides: list[str] | None = None) -> Path:
    """Run (or resume) one training run; returns the path of the final model.zip. Every setting is checked before
    any file is written, and the run folder is locked for the whole run (a second resume of it is refused)."""
    cfg, run_dir, resuming = resolve_run(cfg, Path(output_dir), overrides or [])
    check_model(cfg)
    try:
        check_config(cfg)
        for note in unused_settings(cfg, [] if resuming else overrides or []):
            print(f"note: {note}", file=sys.stderr)
    except (ConfigError, ValueError, OmegaConfBaseException) as err:
        fail(str(err))
    rollout = rollout_size(cfg)
    for key in ("total_timesteps", "checkpoint_every"):  # SB3 trains and saves whole rollouts: record what runs
        whole = -(-int(cfg[key]) // rollout) * rollout
        if whole != int(cfg[key]):
            print(f"note: {key}={cfg[key]} rounds up to {whole} (whole rollouts of {rollout} agent-steps)",
                  file=sys.stderr)  # fmt: skip
            cfg[key] = whole
    try:
        with hold(run_dir / ".lock", f"run folder {str(run_dir)!r}"):
            return _train_locked(cfg, run_dir, resuming)
    except FolderBusy as err:
        fail(str(err))


def _train_locked(cfg: DictConfig, run_dir: Path, resuming: bool) -> Path:
    if not resuming and ((run_dir / "config.yaml").exists() or checkpoints(run_dir / "checkpoints")):
        fail(f"{run_dir} already holds a run: continue it with resume={run_dir}, or train into another folder")
    if resuming and not checkpoints(run_dir / "checkpoints") and (run_dir / "model.zip").exists():
        fail(f"resume={str(run_dir)!r} is a finished run with no checkpoints/ left (a shipped folder): start a new "
             f"run from its weights with init={run_dir / 'model.zip'}")  # fmt: skip
    for folder in (run_dir, run_dir / "checkpoints"):  # left by a killed writer; we hold the folder's lock
        remove_temporaries(folder)
    torch.set_num_threads(int(cfg.threads))
    cfg.device = str(get_device(cfg.device))  # recorded as used (device=auto becomes cpu or cuda)

    # Environment and algorithm: fresh, or the newest readable checkpoint with its step count and optimiser state.
    env = label_env(cfg, make_vec_env(cfg))  # labelled by the teacher when the teacher term needs it
    model, start_step = None, 0
    if not resuming:
        model = make_algorithm(cfg, env, tensorboard_log=None)
        if cfg.init is not None:
            init_weights(model, str(cfg.init))
    else:
        model, checkpoint = load_newest_checkpoint(cfg, run_dir, env)
    if model is None:  # a resume of a run killed before its first checkpoint starts it again, with its config
        print(f"{run_dir} has no checkpoint yet: starting it again from step 0", file=sys.stderr)
        resuming = False
        model = make_algorithm(cfg, env, tensorboard_log=None)
        if cfg.init is not None:
            init_weights(model, str(cfg.init))
        start_step = 0
    elif resuming:
        start_step = model.num_timesteps
        if int(cfg.total_timesteps) < start_step:
            fail(f"total_timesteps={cfg.total_timesteps} is not allowed: {run_dir} has trained {start_step} "
                 f"agent-steps already ({checkpoint.name}); give total_timesteps >= {start_step}")  # fmt: skip
        model.set_random_seed((int(cfg.seed) + start_step) % 2**32)  # new scenarios, not a replay of the first
        print(f"resuming {run_dir} from {checkpoint.name} at {start_step} agent-steps", file=sys.stderr)
    attach_teacher(cfg, model, env)
    clones = cfg.imitation.teacher is not None and int(cfg.imitation.epochs) > 0  # a warm start before RL
    # The run's record, written once the run has started well: a resume writes back what it changed (say
    # total_timesteps) but never what it resumes from.
    record = copy.deepcopy(cfg)
    record.resume = None
    write_text_atomic(run_dir / "config.yaml", OmegaConf.to_yaml(record, resolve=True))
    if not resuming and clones:
        warm_start(cfg, model, run_dir)
        # A kill before the first RL checkpoint then resumes from the clone rather than losing it.
        write_atomic(run_dir / "checkpoints" / "step_0.zip", lambda tmp: model.save(tmp))

    # Logs: one CSV across resumed segments, plus TensorBoard.
    csv_writer = AppendingCSV(run_dir / "progress.csv", resume_step=start_step if resuming else None)
    tensorboard = ResumableTensorBoard(str(run_dir / "tensorboard"), purge_step=start_step + 1 if resuming else None)
    model.set_logger(Logger(str(run_dir), [csv_writer, tensorboard]))

    callbacks = [
        TeamMetricsCallback(),
        AtomicCheckpointCallback(run_dir / "checkpoints", int(cfg.checkpoint_every), int(cfg.keep_checkpoints)),
    ]
    v = cfg.validation
    validation = ValidationCallback(
        world_config(cfg),
        scenario_of(cfg),
        int(v.every),
        int(v.n_worlds),
        int(v.seed),
        v.deterministic,
        at_start=(clones or cfg.init is not None) and not resuming,
    )
    callbacks.append(validation)

    remaining = int(cfg.total_timesteps) - model.num_timesteps
    if remaining > 0:
        model.learn(
            total_timesteps=remaining,
            callback=CallbackList(callbacks),
            log_interval=int(cfg.log_interval),
            reset_num_timesteps=not resuming,
            progress_bar=bool(cfg.progress_bar),
        )
    elif not resuming:  # total_timesteps=0 (a clone only): the score is the clone's
        validation.init_callback(model)
        validation.on_training_end()
    final = write_atomic(run_dir / "model.zip", lambda tmp: model.save(tmp))
    score = write_score(run_dir, int(v.score_last))
    print(f"trained {model.num_timesteps} agent-steps; model: {final}; score {score['score']:.4f} (mean found "
          f"fraction of the last {score['validations']} validations)", file=sys.stderr)  # fmt: skip
    env.close()
    return final


@hydra.main(version_base="1.3", config_path="../../conf", config_name="train")
def main(cfg: DictConfig) -> float:
    """Train, and return the run's score (score.py) for Hydra sweepers: `-m hydra/sweeper=optuna` maximises it."""
    hydra_cfg = HydraConfig.get()
    final = train(cfg, Path(hydra_cfg.runtime.output_dir), list(hydra_cfg.overrides.task))
    return read_score(final.parent)


if __name__ == "__main__":
    check_resume_argument(sys.argv[1:])
    sys.argv[1:] = recipe_arguments(sys.argv[1:])
    main()
