"""A training run's plan: its composed config checked once and read once into the objects every later step uses.

`make_plan(cfg)` refuses a bad value with one ConfigError naming it and what is allowed, before any work or file;
what it returns holds the settings as typed objects (`TrainConfig` and its groups' dataclasses, searchrl/train/
schema.py: no DictConfig and no casts below this module), the world of each group of worlds, the scenario, the
teacher (validated by building it), the algorithm class and the rollout size, so nothing downstream reads or checks
the config again (searchrl/train/app.py builds env, algorithm, teacher and callbacks from it in one flat sequence).
"""

from __future__ import annotations

import copy
import math
import zipfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.utils import get_device

from searchrl.command_line import import_modules
from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.registry import make_teacher, teacher_settings
from searchrl.envs.rewards import make_reward
from searchrl.imitation.clone import lr_factor
from searchrl.imitation.teacher_term import TEACHER_ALGORITHMS, check_settings
from searchrl.multirun import said_as_refusal
from searchrl.policies.algorithms import ALGORITHMS
from searchrl.policies.checkpoint import PolicyRecord, policy_class
from searchrl.policies.device import check_device
from searchrl.policies.extractor import SearchCNN
from searchrl.policies.networks import observation_parts
from searchrl.shared_schema import TRAINABLE_MODELS, check_known_keys, check_threads, check_world_node, override_keys
from searchrl.train.logs import check_logger
from searchrl.train.schema import A2CConfig, ImitationConfig, RecurrentPPOConfig, TrainConfig, typed_parts
from searchrl.world.config import ConfigError, WorldConfig, need
from searchrl.world.scenario import Scenario, ScenarioMix

ALGO_SCHEMAS = {"recurrent_ppo": RecurrentPPOConfig, "a2c": A2CConfig}


@dataclass(frozen=True)
class Plan:
    """What a run is built from. `groups[0]` is env.world with env.n_worlds, then one per env.extra_teams entry."""

    # The composed config as typed objects: total_timesteps and checkpoint_every rounded up to whole rollouts, the
    # device resolved (auto: cpu or cuda). Read, never written, below the plan.
    settings: TrainConfig
    groups: tuple[tuple[WorldConfig, int], ...]  # (world config, K worlds) per group
    scenario: Scenario
    algorithm: type[BaseAlgorithm]  # SB3's class, or its teacher-term subclass (searchrl/imitation/teacher_term.py)
    teacher_term: bool  # RL with the teacher term or critic warm-up
    rollout: int  # agent-steps of one rollout: algo.n_steps × every group's K·N
    notes: tuple[str, ...]  # what the run will not use, or rounds, said before it starts
    teacher_settings: ControllerConfig | None = None  # imitation.teacher with its teacher_args, typed

    @property
    def world(self) -> WorldConfig:
        return self.groups[0][0]

    @property
    def teacher(self) -> str | None:
        """imitation.teacher: a heuristic of the registry, or None."""
        return self.settings.imitation.teacher

    @property
    def clones(self) -> bool:
        """A warm start: the teacher is cloned before RL."""
        return self.teacher is not None and self.settings.imitation.epochs > 0

    def policy_record(self) -> PolicyRecord:
        """What the run's policy is built from, as a checkpoint's loader reads it from the run's config.yaml."""
        s = self.settings
        clip = getattr(s.algo, "clip_range", None)
        return PolicyRecord(
            s.algo.name, s.algo.learning_rate, clip, self.world, s.network, s.critic, tuple(s.extensions)
        )


@said_as_refusal
def make_plan(cfg: DictConfig, overrides: list[str] | tuple[str, ...] = ()) -> Plan:
    """Check every setting of `cfg` (a composed train config) and read it into a Plan holding its typed settings;
    ConfigError naming the first bad value. `overrides` (the command line's) only choose the notes on settings the
    run will not use."""
    import_modules(cfg.get("extensions") or [])  # their parts, in a launcher's job process too
    check_known_keys(cfg)  # `+total_timestep=...` composes: refused here, not trained past
    check_model(cfg)
    algorithm = check_algo(cfg)
    cfg = copy.deepcopy(cfg)  # the caller's stays as it is: the algo node typed below, the budgets rounded
    # A run's config.yaml merged into TrainConfig (resume=) leaves `algo` (Any) untyped: its group's schema types it.
    cfg.algo = OmegaConf.merge(OmegaConf.structured(ALGO_SCHEMAS[cfg.algo.name]), cfg.algo)
    cfg = typed_parts(cfg)  # network, critic and reward typed by their parts' settings (unknown names refused)
    s: TrainConfig = OmegaConf.to_object(cfg)  # typed from here on: the schema checked every value's type
    check_world_node(s.env)
    groups = tuple(team_groups(s))
    scenario = Scenario.from_dict(s.scenario)
    for world, _ in groups:
        scenario.check(world)
    draw_walls(scenario, groups)
    check_device(s.device)
    check_numbers(s)
    rollout = s.algo.n_steps * sum(k * world.n_agents for world, k in groups)
    batch = getattr(s.algo, "batch_size", None)
    need(batch is None or 1 <= batch <= rollout, "algo.batch_size", batch, f"1 <= batch_size <= rollout size {rollout}")
    # A minibatch is whole slots' rollouts (searchrl/policies/slot_buffer.py): a whole number of n_steps.
    need(
        batch is None or batch % s.algo.n_steps == 0,
        "algo.batch_size",
        batch,
        f"a multiple of algo.n_steps={s.algo.n_steps} (minibatches of whole slots' rollouts)",
    )
    check_init(s)
    im = s.imitation
    teacher = None
    if im.teacher is not None:
        teacher = teacher_settings(im.teacher, im.teacher_args)  # an unknown teacher or argument, or a mistyped one
        make_teacher(teacher, groups[0][0], 0)  # a value it refuses
        check_imitation(im)
    teacher_term = im.rl_weight != 0 or im.critic_warmup != 0
    check_teacher_term(s, teacher_term)
    SearchCNN.check_sizes(s.network.conv_channels, s.network.vector_size, s.network.fc_sizes, groups[0][0].fov)
    check_network_choices(s)
    check_logger(s.logger)
    notes = unused_settings(s, list(overrides), groups) + round_to_rollouts(s, rollout)
    algorithm = TEACHER_ALGORITHMS.get(s.algo.name, algorithm)  # the term off (w = 0) where a recipe has none
    s.device = str(get_device(s.device))  # recorded as used (device=auto becomes cpu or cuda)
    return Plan(s, groups, scenario, algorithm, teacher_term, rollout, tuple(notes), teacher)


def draw_walls(scenario: Scenario | ScenarioMix, groups: Sequence[tuple[WorldConfig, int]], draws: int = 4) -> None:
    """Walls are redrawn at a reset until agents and targets fit, and a setting where they never fit (iid walls at
    density 0.9, connected) would stop the run at its first reset, its folder written: each group's walls are drawn
    `draws` times at its smallest and largest side first, from a generator of their own (the run's are untouched).
    ConfigError naming the setting."""
    rng = np.random.default_rng(0)
    for member in dict.fromkeys(getattr(scenario, "scenarios", (scenario,))):
        for world, _ in groups:
            for n in sorted({world.world_size[0], world.world_size[1]}):
                for _ in range(draws):
                    member.obstacles(n, world.n_agents + world.n_targets[1], rng)


def check_model(cfg: DictConfig) -> None:
    """A model chosen with +model= (or an experiment that sets one); the command line named one that exists
    (`command_line.check_group_choices`)."""
    if cfg.model is None:
        raise ConfigError(
            f"choose a model to train with +model=<name>; trainable models: {', '.join(TRAINABLE_MODELS)}"
        )


def check_algo(cfg: DictConfig) -> type[BaseAlgorithm]:
    """SB3's class of algo.name, whose group's settings the config holds."""
    if cfg.algo.name not in ALGORITHMS:
        raise ConfigError(f"algo.name={cfg.algo.name!r} is not allowed: one of {sorted(ALGORITHMS)}")
    expected = {f.name for f in fields(ALGO_SCHEMAS[cfg.algo.name])}
    if set(cfg.algo.keys()) != expected:
        raise ConfigError(
            f"algo.name={cfg.algo.name!r} does not match the algo group's settings {sorted(cfg.algo.keys())}: "
            f"choose the algorithm with algo={cfg.algo.name}, not algo.name="
        )
    return ALGORITHMS[cfg.algo.name][0]


def team_groups(s: TrainConfig) -> list[tuple[WorldConfig, int]]:
    """(world config, K) per group of worlds: env.world with env.n_worlds, then each of env.extra_teams; every K
    times env.replicas."""
    world = WorldConfig.from_dict(asdict(s.env.world))  # ConfigError naming a field
    replicas = s.env.replicas
    need(replicas >= 1, "env.replicas", replicas, "an integer >= 1 (1: the recipe's worlds once)")
    groups = [(world, s.env.n_worlds * replicas)]
    for j, team in enumerate(s.env.extra_teams):
        if team.n_worlds < 1:
            raise ConfigError(f"env.extra_teams[{j}].n_worlds={team.n_worlds!r} is not allowed: must be >= 1")
        try:
            sizes = team.world_size  # n, [low, high] or null (the world's)
            sizes = world.world_size if sizes is None else tuple(sizes) if isinstance(sizes, list) else sizes
            team_world = replace(world, n_agents=team.n_agents, world_size=sizes)
            groups.append((team_world, team.n_worlds * replicas))
        except ConfigError as err:
            raise ConfigError(f"env.extra_teams[{j}]: {err}") from None
    return groups


def check_numbers(cfg: TrainConfig) -> None:
    algo = cfg.algo
    clip = getattr(algo, "clip_range", 0.2)  # PPO's; A2C has none
    numbers = [  # (name, value, ok, allowed); NaN fails every comparison
        ("seed", cfg.seed, 0 <= cfg.seed < 2**32, "0 <= seed < 2**32 (numpy and torch seeds)"),
        ("validation.seed", cfg.validation.seed, cfg.validation.seed >= 0, "an integer >= 0"),
        ("algo.learning_rate", algo.learning_rate, 0 < algo.learning_rate < math.inf, "a number > 0"),
        ("algo.gamma", algo.gamma, 0 < algo.gamma <= 1, "0 < gamma <= 1"),
        ("algo.gae_lambda", algo.gae_lambda, 0 <= algo.gae_lambda <= 1, "0 <= gae_lambda <= 1"),
        ("algo.ent_coef", algo.ent_coef, 0 <= algo.ent_coef < math.inf, "a number >= 0"),
        ("algo.vf_coef", algo.vf_coef, 0 <= algo.vf_coef < math.inf, "a number >= 0"),
        ("algo.max_grad_norm", algo.max_grad_norm, 0 < algo.max_grad_norm < math.inf, "a number > 0"),
        ("algo.clip_range", clip, 0 < clip < math.inf, "a number > 0"),
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
        "algo.n_epochs": getattr(cfg.algo, "n_epochs", 1),
        "network.lstm_hidden_size": cfg.network.lstm_hidden_size,
    }
    for name, value in positive.items():
        if value < 1:
            raise ConfigError(f"{name}={value!r} is not allowed: must be >= 1")
    check_threads(cfg.threads)
    # 0 agent-steps of RL is a clone-only run: model.zip is the policy fitted to the teacher (or the init weights).
    no_start = cfg.imitation.teacher is None and cfg.init is None
    if cfg.total_timesteps < 0 or (cfg.total_timesteps == 0 and no_start):
        raise ConfigError(
            f"total_timesteps={cfg.total_timesteps!r} is not allowed: must be >= 1, or 0 with imitation.teacher "
            "or init (a run without RL)"
        )
    need(
        cfg.validation.every >= 0,
        "validation.every",
        cfg.validation.every,
        ">= 0 agent-steps between validations (0: only the final model's)",
    )
    for key in ("n_worlds", "score_last"):
        need(getattr(cfg.validation, key) >= 1, f"validation.{key}", getattr(cfg.validation, key), ">= 1")


def check_network_choices(cfg: TrainConfig) -> None:
    """reward, network.extractor and critic.name registered, their grids large enough, and a run that can feed them."""
    make_reward(cfg.reward)
    parts = observation_parts(cfg.network, cfg.critic)  # unregistered names, with the nearest
    policy_class(cfg.algo.name, cfg.critic)  # a critic of its own needs RecurrentPPO
    for name, value in (("network.grid", cfg.network.grid), ("critic.grid", cfg.critic.grid)):
        need(value >= 4, name, value, "an integer >= 4 (two stride-2 convolutions)")
    if parts and cfg.imitation.teacher is not None and cfg.imitation.epochs > 0:
        need(
            False,
            "imitation.epochs",
            cfg.imitation.epochs,
            f"0 with network.extractor={cfg.network.extractor} or "
            f"critic.name={cfg.critic.name} (cloning records the window and 3-vector only): start from a clone "
            "with init=",
        )


def check_init(cfg: TrainConfig) -> None:
    """init= names a model zip (a resumed run continues from its checkpoint and no longer needs it)."""
    if cfg.init is not None and cfg.resume is None:
        if not Path(cfg.init).is_file():
            need(False, "init", cfg.init, "an existing model.zip, imitation.zip or checkpoint of a run")
        need(zipfile.is_zipfile(cfg.init), "init", cfg.init, "a model zip written by searchrl.train (this is not one)")


def check_imitation(im: ImitationConfig) -> None:
    for name in ("episodes", "batch_sequences"):
        need(getattr(im, name) >= 1, f"imitation.{name}", getattr(im, name), "must be >= 1")
    for name in ("epochs", "value_epochs"):
        need(getattr(im, name) >= 0, f"imitation.{name}", getattr(im, name), "must be >= 0")
    need(0 < im.learning_rate < math.inf, "imitation.learning_rate", im.learning_rate, "must be > 0")
    lr_factor(im.lr_schedule, 0, 1)  # an unknown schedule, named


def check_teacher_term(cfg: TrainConfig, teacher_term: bool) -> None:
    im = cfg.imitation
    weight = im.rl_weight
    check_settings(weight, im.rl_schedule, im.critic_warmup)
    need(im.rl_anneal_steps >= 1, "imitation.rl_anneal_steps", im.rl_anneal_steps, "an integer >= 1 (agent-steps)")
    if weight > 0 and im.teacher is None:
        need(False, "imitation.rl_weight", weight, "0 without imitation.teacher (the term imitates the teacher)")
    if teacher_term and cfg.algo.name not in TEACHER_ALGORITHMS:
        need(
            False,
            "algo",
            cfg.algo.name,
            f"one of {', '.join(TEACHER_ALGORITHMS)} with imitation.rl_weight or "
            "imitation.critic_warmup (the teacher term is a PPO loss term)",
        )


def unused_settings(cfg: TrainConfig, overrides: list[str], groups: tuple[tuple[WorldConfig, int], ...]) -> list[str]:
    """Notes on what this run will not use that the command line set: imitation settings without a teacher, the
    LSTM size of a feed-forward algorithm, a minibatch larger than the demonstrations. (Validation settings always
    count: the final model is validated for the run's score even with validation.every=0.) Said, not refused: a
    sweep over `imitation.teacher=null,greedy` or `algo=a2c,recurrent_ppo` keeps one command line for all its
    jobs."""
    keys = override_keys(overrides)
    unused = []
    if cfg.imitation.teacher is None:
        used = ("imitation.teacher", "imitation.critic_warmup")
        unused += [k for k in keys if k.startswith("imitation.") and k not in used]
    if cfg.algo.name != "recurrent_ppo":
        unused += [k for k in keys if k == "network.lstm_hidden_size"]
    notes = [f"{k} has no effect here (no imitation.teacher, or a feed-forward algo)" for k in unused]
    sequences = sum(k * world.n_agents for world, k in groups) * cfg.imitation.episodes
    if cfg.imitation.teacher is not None and cfg.imitation.batch_sequences > sequences:
        notes.append(
            f"imitation.batch_sequences={cfg.imitation.batch_sequences} is more than the {sequences} teacher "
            "sequences: each minibatch holds all of them"
        )
    return notes


def round_to_rollouts(cfg: TrainConfig, rollout: int) -> list[str]:
    """Round total_timesteps and checkpoint_every up to whole rollouts in `cfg` (SB3 trains and saves whole
    rollouts: the config then records what runs); a note for each changed."""
    notes = []
    for key in ("total_timesteps", "checkpoint_every"):
        given = getattr(cfg, key)
        whole = -(-given // rollout) * rollout
        if whole != given:
            notes.append(f"{key}={given} rounds up to {whole} (whole rollouts of {rollout} agent-steps)")
            setattr(cfg, key, whole)
    return notes
