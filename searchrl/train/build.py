"""How a training run starts from its Plan (searchrl/train/plan.py): its folder checked and cleared, the objects it
is built from (VecEnv, teacher labels, SB3 algorithm), its model (fresh, from `init=` weights, or resumed from its
newest checkpoint of this run), the teacher's clone before RL, and its logs continued across resumed segments."""

from __future__ import annotations

import sys
from dataclasses import asdict
from pathlib import Path

import pandas as pd
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import VecEnv

from searchrl.atomic import check_own_files, check_writable, remove_temporaries, write_text_atomic
from searchrl.command_line import held_run
from searchrl.envs.rewards import make_reward
from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.imitation.clone import clone, collect
from searchrl.imitation.teacher_labels import TeacherLabels
from searchrl.imitation.teacher_term import TeacherTerm
from searchrl.multirun import refuse
from searchrl.policies.checkpoint import (
    PolicyRecord,
    load_checkpoint,
    policy_class,
    policy_record,
    run_config,
    save_model,
)
from searchrl.policies.networks import observation_parts, policy_kwargs
from searchrl.threads import use_threads
from searchrl.train.callbacks import checkpoints
from searchrl.train.logs import AppendingCSV, ContinuedClock, ResumableTensorBoard, clock_offsets, start_wandb
from searchrl.train.plan import Plan
from searchrl.train.run_record import foreign_checkpoint, run_identity, set_aside_logs
from searchrl.train.schema import TrainConfig
from searchrl.world.config import ConfigError


def prepare_folder(cfg: TrainConfig, run_dir: Path, resuming: bool) -> None:
    """Refuse a folder that holds another run (or a finished one with nothing to resume from), clear what a killed
    writer left, and set torch's and numba's threads as the run records them."""
    if not resuming and (held := held_run(run_dir)):
        refuse(held)
    if resuming and not checkpoints(run_dir / "checkpoints") and (run_dir / "model.zip").exists():
        refuse(
            f"resume={str(run_dir)!r} is a finished run with no checkpoints/ left (a shipped folder): start a new "
            f"run from its weights with init={run_dir / 'model.zip'}"
        )
    check_own_files(run_dir, "resume" if resuming else "hydra.run.dir")  # a checkpoints/ linked elsewhere
    for folder in (run_dir, run_dir / "checkpoints"):  # a folder made read-only: said now, not after a rollout
        check_writable(folder, "resume" if resuming else "hydra.run.dir", folder=True)
    for folder in (run_dir, run_dir / "checkpoints"):  # left by a killed writer; we hold the folder's lock
        remove_temporaries(folder)
    use_threads(cfg.threads, network_on_cpu=cfg.device == "cpu")  # torch's and the world's (numba's)


def make_vec_env(plan: Plan, seed: int | None = None) -> VecEnv:
    """One SearchVecEnv, or a TeamMixVecEnv when env.extra_teams adds groups (group j seeded with seed + j); with
    the teacher term, wrapped to label every step with the teacher's action (`TeacherLabels`)."""
    parts = observation_parts(plan.settings.network, plan.settings.critic)
    reward = make_reward(plan.settings.reward)
    envs = [
        SearchVecEnv(
            world,
            n_worlds=k,
            seed=None if seed is None else seed + j,
            scenario=plan.scenario,
            parts=parts,
            reward=reward,
        )
        for j, (world, k) in enumerate(plan.groups)
    ]
    env = envs[0] if len(envs) == 1 else TeamMixVecEnv(envs)
    if plan.teacher_term and plan.teacher_settings is not None:
        return TeacherLabels(env, plan.teacher_settings, plan.settings.seed)
    return env


def start_model(plan: Plan, run_dir: Path, env: VecEnv, resuming: bool) -> tuple[BaseAlgorithm, bool]:
    """(the algorithm, whether it resumes): the newest readable checkpoint with its step count and optimiser state,
    or a fresh one (from init= weights if given), also for a resume of a run killed before its first checkpoint."""
    cfg = plan.settings
    if resuming:
        model, checkpoint = load_newest_checkpoint(plan, run_dir, env)
        if model is not None:
            start = model.num_timesteps
            if cfg.total_timesteps < start:
                refuse(
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
        fresh = init_weights(model, cfg.init, plan.policy_record())
        print(f"policy weights from {cfg.init}" + (f"; fresh: {', '.join(fresh)}" if fresh else ""), file=sys.stderr)
    return model, False


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
            model = None if problem else load_algorithm(plan, str(path), env)
        except OSError as err:  # cannot be read now (permission, I/O): maybe whole, so nothing is set aside
            refuse(
                f"resume={plan.settings.resume!r}: {path.name} cannot be read now ({type(err).__name__}: "
                f"{err.strerror or err}); nothing was renamed: restore access and resume again"
            )
        except ValueError as err:
            aside = path.with_name(f"{path.name}.unreadable")
            path.rename(aside)
            print(f"warning: {err}; set aside as {aside.name}, trying the checkpoint before it", file=sys.stderr)
            continue
        if problem:
            refuse(f"resume={plan.settings.resume!r}: checkpoints/{path.name} {problem}; nothing was changed")
        return model, path
    refuse(f"resume={plan.settings.resume!r}: no checkpoint under checkpoints/ can be read (set aside as *.unreadable)")


def load_algorithm(plan: Plan, path: str, env: VecEnv) -> BaseAlgorithm:
    """A checkpoint with its step count and optimiser state, attached to `env` (and its teacher labels); ValueError
    naming the file if it cannot be read."""
    model = load_checkpoint(path, plan.policy_record(), cls=plan.algorithm, env=env, device=plan.settings.device)
    attach_teacher(plan, model, env)
    return model


def make_algorithm(plan: Plan, env: VecEnv) -> BaseAlgorithm:
    """A fresh algorithm on `env`, with the teacher term's settings and labels where the run uses them."""
    s = plan.settings
    algo = asdict(s.algo)
    algo.pop("name")
    model = plan.algorithm(
        policy_class(s.algo.name, s.critic),
        env,
        seed=s.seed,
        device=s.device,
        policy_kwargs=policy_kwargs(s.network, s.algo.name, s.critic),
        verbose=0,
        **algo,
    )
    attach_teacher(plan, model, env)
    return model


def attach_teacher(plan: Plan, model: BaseAlgorithm, env: VecEnv) -> None:
    """Give a teacher-term algorithm its settings and the wrapper's labels (None without a teacher)."""
    if isinstance(model, TeacherTerm):
        im = plan.settings.imitation
        source = env if isinstance(env, TeacherLabels) else None
        model.configure_teacher(im.rl_weight, im.rl_schedule, im.critic_warmup, source, im.rl_anneal_steps)


def init_weights(model: BaseAlgorithm, path: str, record: PolicyRecord) -> list[str]:
    """Copy the policy weights of checkpoint `path` (read as `load_checkpoint` reads any file, by its own run's
    config, or by `record` for a file without one beside it) into the fresh `model` of a run of `record`; its
    optimiser state is not taken. Every tensor the
    two policies both have is copied and must have the same shape, and the actor's head must be among them, so a
    policy of another size or action set is refused (ConfigError with the reason); the parts only `model` has (a
    whole-map branch, a critic of its own) keep their fresh weights. Returns the names of those parts."""
    try:
        try:
            own = policy_record(run_config(path), path)
        except FileNotFoundError:  # a zip copied out of its run: read as this run's network
            own = record
        theirs = load_checkpoint(path, own, device="cpu").policy.state_dict()
    except ValueError as err:  # a zip of no run, a corrupt file: all end here
        raise ConfigError(f"init={path!r} does not fit this run's policy: {err}") from None
    ours = model.policy.state_dict()
    shared = [name for name in ours if name in theirs]
    wrong = [name for name in shared if ours[name].shape != theirs[name].shape]
    if wrong or "action_net.weight" not in shared:
        why = (
            f"{wrong[0]} is {tuple(theirs[wrong[0]].shape)} there, {tuple(ours[wrong[0]].shape)} here"
            if wrong
            else "it has no actor head of this policy"
        )
        raise ConfigError(
            f"init={path!r} does not fit this run's policy (algo, network, observation and action "
            f"spaces must match): {why}"
        )
    model.policy.load_state_dict({**ours, **{name: theirs[name] for name in shared}})
    # named_parameters names a module shared under two names (the actor's extractor) once
    fresh = [name for name, _ in model.policy.named_parameters() if name not in theirs]
    return sorted({".".join(name.split(".")[:2]) for name in fresh})


def warm_start(plan: Plan, model: BaseAlgorithm, run_dir: Path) -> None:
    """Clone the teacher into the fresh policy (searchrl/imitation/clone.py); imitation.csv records each epoch,
    imitation.zip the clone before RL, and checkpoints/step_0.zip too, so a kill before the first RL checkpoint
    resumes from it."""
    im, seed = plan.settings.imitation, plan.settings.seed
    demos = collect(
        list(plan.groups),
        plan.teacher_settings,
        im.episodes,
        plan.settings.algo.gamma,
        seed,
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
