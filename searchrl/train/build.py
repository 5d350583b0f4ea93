"""The one place where a composed config becomes objects: world config, VecEnv, SB3 algorithm."""

from __future__ import annotations

import math
import zipfile
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecEnv

from searchrl.controllers.policy import load_checkpoint
from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.policies.algorithms import ALGORITHMS
from searchrl.policies.extractor import SearchCNN
from searchrl.policies.teacher_term import TEACHER_ALGORITHMS, TeacherTerm, check_settings
from searchrl.train.imitation import lr_factor, make_teacher
from searchrl.train.schema import A2CConfig, PPOConfig, RecurrentPPOConfig, override_keys
from searchrl.train.teacher_labels import TeacherLabels
from searchrl.world.config import ConfigError, WorldConfig, need
from searchrl.world.scenario import Scenario

ALGO_SCHEMAS = {"recurrent_ppo": RecurrentPPOConfig, "ppo": PPOConfig, "a2c": A2CConfig}
TRAINABLE_MODELS = ("a", "b", "c", "diagonal")


def world_config(cfg: DictConfig) -> WorldConfig:
    """The validated engine config of `env.world` (model presets have already written Φ, comm, actions)."""
    return WorldConfig.from_dict(OmegaConf.to_container(cfg.env.world, resolve=True))


def scenario_of(cfg: DictConfig) -> Scenario:
    """The run's scenario (`scenario`, conf/scenario/); the paper's for a config without one."""
    node = cfg.get("scenario")
    return Scenario.from_dict(None if node is None else OmegaConf.to_container(node, resolve=True))


def team_groups(cfg: DictConfig) -> list[tuple[WorldConfig, int]]:
    """(world config, K) per group of worlds: env.world with env.n_worlds, then each of env.extra_teams."""
    world = world_config(cfg)
    groups = [(world, int(cfg.env.n_worlds))]
    for j, team in enumerate(cfg.env.extra_teams):
        if int(team.n_worlds) < 1:
            raise ConfigError(f"env.extra_teams[{j}].n_worlds={team.n_worlds!r} is not allowed: must be >= 1")
        try:
            sizes = OmegaConf.to_container(team, resolve=True)["world_size"]  # n, [low, high] or null (the world's)
            sizes = world.world_size if sizes is None else tuple(sizes) if isinstance(sizes, list) else sizes
            groups.append((replace(world, n_agents=int(team.n_agents), world_size=sizes), int(team.n_worlds)))
        except ConfigError as err:
            raise ConfigError(f"env.extra_teams[{j}]: {err}") from None
    return groups


def make_vec_env(cfg: DictConfig, seed: int | None = None) -> VecEnv:
    """One SearchVecEnv, or a TeamMixVecEnv when env.extra_teams adds groups (group j seeded with seed + j)."""
    scenario = scenario_of(cfg)
    envs = [SearchVecEnv(world, n_worlds=k, seed=None if seed is None else seed + j, scenario=scenario)
            for j, (world, k) in enumerate(team_groups(cfg))]  # fmt: skip
    return envs[0] if len(envs) == 1 else TeamMixVecEnv(envs)


def _algo_kwargs(cfg: DictConfig) -> dict[str, Any]:
    kwargs = OmegaConf.to_container(cfg.algo, resolve=True)
    kwargs.pop("name")
    return kwargs


def policy_kwargs(cfg: DictConfig) -> dict[str, Any]:
    net = cfg.network
    kwargs: dict[str, Any] = {
        "features_extractor_class": SearchCNN,
        "features_extractor_kwargs": {
            "conv_channels": list(net.conv_channels),
            "vector_size": int(net.vector_size),
            "fc_sizes": list(net.fc_sizes),
        },
        "net_arch": [],  # policy and value heads are linear on the features (or the LSTM output), as in PRIMAL
    }
    if cfg.algo.name == "recurrent_ppo":
        kwargs["lstm_hidden_size"] = int(net.lstm_hidden_size)
    return kwargs


def check_config(cfg: DictConfig) -> None:
    """Fail before any work with a message naming the bad value and what is allowed."""
    if cfg.algo.name not in ALGORITHMS:
        raise ConfigError(f"algo.name={cfg.algo.name!r} is not allowed: one of {sorted(ALGORITHMS)}")
    expected = {f.name for f in fields(ALGO_SCHEMAS[cfg.algo.name])}
    if set(cfg.algo.keys()) != expected:
        raise ConfigError(
            f"algo.name={cfg.algo.name!r} does not match the algo group's settings {sorted(cfg.algo.keys())}: "
            f"choose the algorithm with algo={cfg.algo.name}, not algo.name="
        )
    world = world_config(cfg)  # raises ConfigError naming the field
    scenario = scenario_of(cfg)
    for group, _ in team_groups(cfg):
        scenario.check(group)
    check_device(str(cfg.device))
    algo = cfg.algo
    numbers = [  # (name, value, ok, allowed); NaN fails every comparison
        ("seed", cfg.seed, 0 <= cfg.seed < 2**32, "0 <= seed < 2**32 (numpy and torch seeds)"),
        ("validation.seed", cfg.validation.seed, cfg.validation.seed >= 0, "an integer >= 0"),
        ("algo.learning_rate", algo.learning_rate, 0 < algo.learning_rate < math.inf, "a number > 0"),
        ("algo.gamma", algo.gamma, 0 < algo.gamma <= 1, "0 < gamma <= 1"),
        ("algo.gae_lambda", algo.gae_lambda, 0 <= algo.gae_lambda <= 1, "0 <= gae_lambda <= 1"),
        ("algo.ent_coef", algo.ent_coef, 0 <= algo.ent_coef < math.inf, "a number >= 0"),
        ("algo.vf_coef", algo.vf_coef, 0 <= algo.vf_coef < math.inf, "a number >= 0"),
        ("algo.max_grad_norm", algo.max_grad_norm, 0 < algo.max_grad_norm < math.inf, "a number > 0"),
        ("algo.clip_range", algo.get("clip_range", 0.2), 0 < algo.get("clip_range", 0.2) < math.inf, "a number > 0"),
    ]
    for name, value, ok, allowed in numbers:
        need(bool(ok), name, value, allowed)
    positive = {
        "env.n_worlds": cfg.env.n_worlds,
        "checkpoint_every": cfg.checkpoint_every,
        "threads": cfg.threads,
        "algo.n_steps": cfg.algo.n_steps,
        "log_interval": cfg.log_interval,
        "keep_checkpoints": cfg.keep_checkpoints,
        "algo.n_epochs": cfg.algo.get("n_epochs", 1),
        "network.lstm_hidden_size": cfg.network.lstm_hidden_size,
    }
    for name, value in positive.items():
        if int(value) < 1:
            raise ConfigError(f"{name}={value!r} is not allowed: must be >= 1")
    # 0 agent-steps of RL is a clone-only run: model.zip is the policy fitted to the teacher (or the init weights).
    no_start = cfg.imitation.teacher is None and cfg.get("init") is None
    if int(cfg.total_timesteps) < 0 or (int(cfg.total_timesteps) == 0 and no_start):
        raise ConfigError(
            f"total_timesteps={cfg.total_timesteps!r} is not allowed: must be >= 1, or 0 with imitation.teacher "
            "or init (a run without RL)"
        )
    if int(cfg.validation.every) < 0 or int(cfg.validation.n_worlds) < 1 or int(cfg.validation.score_last) < 1:
        raise ConfigError(
            f"validation={dict(cfg.validation)!r} is not allowed: every >= 0, n_worlds >= 1 and score_last >= 1"
        )
    rollout = rollout_size(cfg)
    batch = cfg.algo.get("batch_size")
    if batch is not None and not 1 <= int(batch) <= rollout:
        raise ConfigError(f"algo.batch_size={batch!r} is not allowed: 1 <= batch_size <= rollout size {rollout}")
    # A resumed run continues from its checkpoint; the file it was initialised from is no longer needed.
    if cfg.get("init") is not None and cfg.get("resume") is None:
        if not Path(cfg.init).is_file():
            need(False, "init", cfg.init, "an existing model.zip, imitation.zip or checkpoint of a run")
        need(zipfile.is_zipfile(cfg.init), "init", cfg.init, "a model zip written by searchrl.train (this is not one)")
    imitation = cfg.imitation
    if imitation.teacher is not None:
        make_teacher(imitation.teacher, world, 0, teacher_args(cfg))  # unknown teacher or bad arguments
        for name in ("episodes", "batch_sequences"):
            if int(imitation[name]) < 1:
                raise ConfigError(f"imitation.{name}={imitation[name]!r} is not allowed: must be >= 1")
        for name in ("epochs", "value_epochs"):
            if int(imitation[name]) < 0:
                raise ConfigError(f"imitation.{name}={imitation[name]!r} is not allowed: must be >= 0")
        lr = float(imitation.learning_rate)
        need(0 < lr < math.inf, "imitation.learning_rate", imitation.learning_rate, "must be > 0")
        lr_factor(str(imitation.get("lr_schedule", "constant")), 0, 1)  # an unknown schedule, named
    check_teacher_term(cfg)
    net = cfg.network
    SearchCNN.check_sizes(list(net.conv_channels), int(net.vector_size), list(net.fc_sizes), world.fov)


def uses_teacher_term(cfg: DictConfig) -> bool:
    """Whether RL runs with the teacher term or critic warm-up (searchrl/policies/teacher_term.py)."""
    return float(cfg.imitation.rl_weight) != 0 or int(cfg.imitation.critic_warmup) != 0


def check_teacher_term(cfg: DictConfig) -> None:
    im = cfg.imitation
    weight = float(im.rl_weight)
    check_settings(weight, str(im.rl_schedule), int(im.critic_warmup))
    if weight > 0 and im.teacher is None:
        need(False, "imitation.rl_weight", weight, "0 without imitation.teacher (the term imitates the teacher)")
    if uses_teacher_term(cfg) and cfg.algo.name not in TEACHER_ALGORITHMS:
        need(False, "algo", cfg.algo.name, f"one of {', '.join(TEACHER_ALGORITHMS)} with imitation.rl_weight or "
             "imitation.critic_warmup (the teacher term is a PPO loss term)")  # fmt: skip


def unused_settings(cfg: DictConfig, overrides: list[str]) -> list[str]:
    """Notes on what this run will not use that the command line set: imitation settings without a teacher, the
    LSTM size of a feed-forward algorithm, a minibatch larger than the demonstrations. (Validation settings always
    count: the final model is validated for the run's score even with validation.every=0.) Said, not refused: a
    sweep over `imitation.teacher=null,greedy` or `algo=ppo,recurrent_ppo` keeps one command line for all its
    jobs."""
    keys = override_keys(overrides)
    unused = []
    if cfg.imitation.teacher is None:
        used = ("imitation.teacher", "imitation.critic_warmup")
        unused += [k for k in keys if k.startswith("imitation.") and k not in used]
    if cfg.algo.name != "recurrent_ppo":
        unused += [k for k in keys if k == "network.lstm_hidden_size"]
    notes = [f"{k} has no effect here (no imitation.teacher, or a feed-forward algo)" for k in unused]
    sequences = team_slots(cfg) * int(cfg.imitation.episodes)
    if cfg.imitation.teacher is not None and int(cfg.imitation.batch_sequences) > sequences:
        notes.append(f"imitation.batch_sequences={cfg.imitation.batch_sequences} is more than the {sequences} teacher "
                     "sequences: each minibatch holds all of them")  # fmt: skip
    return notes


def team_slots(cfg: DictConfig) -> int:
    """Slots (agents) of every world of every group: K·N summed over env.world and env.extra_teams."""
    return sum(k * group.n_agents for group, k in team_groups(cfg))


def rollout_size(cfg: DictConfig) -> int:
    """Agent-steps of one rollout: algo.n_steps × team_slots. SB3 trains and saves whole rollouts."""
    return int(cfg.algo.n_steps) * team_slots(cfg)


def check_device(device: str) -> None:
    """ConfigError unless torch can run on `device` here: a run never falls back to the CPU unasked."""
    allowed = "cpu, cuda, cuda:<index>, mps or auto (cuda when torch sees one, else cpu)"
    if device == "auto":
        return
    try:
        parsed = torch.device(device)
    except (RuntimeError, ValueError):
        raise ConfigError(f"device={device!r} is not allowed: {allowed}") from None
    if parsed.type == "cuda":
        count = torch.cuda.device_count()
        need(count > 0, "device", device, "cpu here: torch sees no CUDA device (torch.cuda.is_available() is False)")
        need((parsed.index or 0) < count, "device", device, f"a CUDA index below {count} (devices torch sees)")
    elif parsed.type == "mps":
        need(torch.backends.mps.is_available(), "device", device, "cpu here: torch sees no MPS device")
    else:
        need(parsed.type == "cpu", "device", device, allowed)


def algorithm_class(cfg: DictConfig) -> type[BaseAlgorithm]:
    """SB3's class of algo.name, or its teacher-term subclass when the run uses the term or critic warm-up."""
    return TEACHER_ALGORITHMS[cfg.algo.name] if uses_teacher_term(cfg) else ALGORITHMS[cfg.algo.name][0]


def label_env(cfg: DictConfig, env: VecEnv) -> VecEnv:
    """`env` wrapped to label every step with the teacher's action when the teacher term needs them."""
    if not uses_teacher_term(cfg) or cfg.imitation.teacher is None:
        return env
    return TeacherLabels(env, str(cfg.imitation.teacher), teacher_args(cfg), int(cfg.seed))


def attach_teacher(cfg: DictConfig, model: BaseAlgorithm, env: VecEnv) -> None:
    """Give a teacher-term algorithm its settings and the wrapper's labels (None without a teacher)."""
    if isinstance(model, TeacherTerm):
        im = cfg.imitation
        source = env if isinstance(env, TeacherLabels) else None
        model.configure_teacher(float(im.rl_weight), str(im.rl_schedule), int(im.critic_warmup), source)


def make_algorithm(cfg: DictConfig, env: VecEnv, tensorboard_log: str | None) -> BaseAlgorithm:
    algo_class, policy = algorithm_class(cfg), ALGORITHMS[cfg.algo.name][1]
    return algo_class(
        policy,
        env,
        seed=int(cfg.seed),
        device=cfg.device,
        policy_kwargs=policy_kwargs(cfg),
        tensorboard_log=tensorboard_log,
        verbose=0,
        **_algo_kwargs(cfg),
    )


def load_algorithm(cfg: DictConfig, path: str, env: VecEnv) -> BaseAlgorithm:
    """Load a checkpoint with its step count and optimiser state, attached to `env`; ValueError naming the file
    if it cannot be read."""
    return load_checkpoint(path, cfg.algo.name, cls=algorithm_class(cfg), env=env, device=cfg.device)


def teacher_args(cfg: DictConfig) -> dict[str, Any]:
    """`imitation.teacher_args` as a plain dict (keyword arguments of the teacher's controller)."""
    return dict(OmegaConf.to_container(cfg.imitation.teacher_args, resolve=True) or {})
