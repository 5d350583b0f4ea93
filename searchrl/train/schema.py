"""Hydra schemas: one dataclass per config group, registered in the ConfigStore and named by the YAML files in
`conf/` (`defaults: [<group>_schema]`). They live outside `__main__` so submitit can unpickle them.

conf/env, conf/model, conf/scenario -> searchrl/shared_schema.py (shared with evaluation)
conf/algo      -> RecurrentPPOConfig | A2CConfig
conf/network   -> NetworkConfig (searchrl/policies/networks.py), or a registered network's schema: network=<name>
conf/critic    -> CriticConfig, or a registered critic's likewise
reward         -> RewardConfig, or a registered reward's (reward=<name>; stored, no yaml)
conf/train.yaml-> TrainConfig

A part's settings extend its node's base dataclass (`Registry.schema`): `network=swept_cnn network.width=64` composes
as the swept network's settings, typed by Hydra; `typed_parts` types a node whose part was chosen by value
(`network.extractor=swept_cnn`) or read from a saved config.yaml the same way, so the settings are one dataclass
from the command line to the policy.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omegaconf import MISSING, DictConfig, OmegaConf

from searchrl.envs.rewards import REWARDS, RewardConfig, reward_schema
from searchrl.migrations import upgrade_run_config
from searchrl.policies.checkpoint import typed_node
from searchrl.policies.networks import CRITICS, NETWORKS, CriticConfig, NetworkConfig, critic_schema, network_schema
from searchrl.shared_schema import (
    CONF_DIR,
    EnvConfig,
    ModelConfig,
    override_keys,
    register_shared_configs,
    repository_root,
    scenario_default,
)
from searchrl.world.config import ConfigError


@dataclass
class LoggerConfig:
    """Where the run's metrics go besides progress.csv and TensorBoard (always written): `wandb` also logs every row
    to Weights & Biases (searchrl/train/logs.py; `pip install -e '.[track]'`)."""

    name: str = "default"  # default: progress.csv and TensorBoard; wandb: those and a W&B run
    project: str = "searchrl"
    entity: str | None = None  # the W&B team or user (null: the account's default)
    mode: str = "offline"  # offline (written under <run>/wandb/, `wandb sync` uploads it) or online
    group: str | None = None  # runs grouped in the W&B interface (say a sweep's seeds)


@dataclass
class AlgoConfig:
    name: str = MISSING
    learning_rate: float = 3e-4
    n_steps: int = 32  # steps per slot per rollout (rollout = n_steps · K · N agent-steps)
    gamma: float = 0.99
    gae_lambda: float = 0.95
    ent_coef: float = 0.01  # σ_H of eq. 12
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5


@dataclass
class RecurrentPPOConfig(AlgoConfig):
    name: str = "recurrent_ppo"  # sb3-contrib's RecurrentPPO; the LSTM size comes from the network group
    batch_size: int = 1024
    n_epochs: int = 4
    clip_range: float = 0.2


@dataclass
class A2CConfig(AlgoConfig):
    name: str = "a2c"  # the synchronous A3C of §4.2
    learning_rate: float = 7e-4
    n_steps: int = 8


@dataclass
class ValidationConfig:
    every: int = 250_000  # agent-steps between validations; 0: only the final model's, which training always runs
    n_worlds: int = 32  # fixed validation worlds, N = env.world.n_agents each
    seed: int = 1_000_000  # disjoint from training seeds (small integers)
    deterministic: bool = False  # argmax actions can deadlock against walls and other agents; sample instead
    score_last: int = 3  # the run's score (score.json, what a sweeper optimises): mean of the last validations


@dataclass
class ImitationConfig:
    """Warm start by cloning a heuristic before RL (`searchrl/imitation/clone.py`); not in the paper."""

    # A heuristic of searchrl/controllers/registry.py but random (registry.teachers()); null
    # trains from scratch as the paper does
    teacher: str | None = None
    # Keyword arguments of the teacher's controller (those of controller=<teacher>), e.g. {horizon: 1} for greedy;
    # empty: that controller's defaults.
    teacher_args: dict[str, Any] = field(default_factory=dict)
    episodes: int = 32  # teacher episodes per world of the run's rollout worlds (K·N·episodes sequences)
    epochs: int = 4  # cross-entropy on the teacher's actions; 0: no clone before RL (nothing is collected)
    value_epochs: int = 1  # then the value-only parameters on the teacher's discounted returns (0 skips)
    batch_sequences: int = 16  # whole episodes per minibatch
    learning_rate: float = 1e-3
    # "linear": each fit's rate falls from learning_rate to 0 over its minibatches; "constant" keeps it.
    lr_schedule: str = "constant"
    # During RL (searchrl/imitation/teacher_term.py): PPO's loss gains rl_weight × the cross-entropy toward the
    # teacher's action on every state the learner visits (0: plain PPO); "linear" takes the weight to 0 by the end
    # of the run. epochs=0 skips the clone (say with init= a clone made before).
    rl_weight: float = 0.0
    rl_schedule: str = "constant"
    rl_anneal_steps: int = 3_000_000  # agent-steps over which rl_schedule=anneal brings rl_weight to 0
    # The first critic_warmup rollouts of RL fit only the value-only parameters on the learner's own returns; the
    # policy does not move until the critic knows the learner's states. Needs no teacher.
    critic_warmup: int = 0


@dataclass
class TrainConfig:
    env: EnvConfig = field(default_factory=EnvConfig)
    model: ModelConfig | None = None  # chosen with +model=<name>
    algo: Any = MISSING
    network: NetworkConfig = field(default_factory=NetworkConfig)
    critic: CriticConfig = field(default_factory=CriticConfig)
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    validation: ValidationConfig = field(default_factory=ValidationConfig)
    imitation: ImitationConfig = field(default_factory=ImitationConfig)
    # What a reset draws besides the sizes and the prior: obstacles, where the targets lie (conf/scenario/,
    # searchrl/world/scenario.py); the paper's by default.
    scenario: dict[str, Any] = field(default_factory=scenario_default)
    seed: int = 0
    total_timesteps: int = 18_400_000  # agent-steps; the paper's ≈ 9000 episodes × 8 agents × 256 steps
    checkpoint_every: int = 500_000  # agent-steps
    keep_checkpoints: int = 3  # newest checkpoints kept on disk
    resume: str | None = None  # a run directory to continue
    # A checkpoint whose policy weights start this run (fine-tuning, e.g. from a run's imitation.zip); the step
    # count and optimiser start afresh. Same observation and action spaces and network needed.
    init: str | None = None
    threads: int = 2  # torch's; the world's too off the CPU (searchrl/threads.py); bit-reproducible on the CPU
    device: str = "cpu"
    progress_bar: bool = True
    log_interval: int = 1  # rollouts between log rows
    extensions: list[str] = field(default_factory=list)  # modules that register parts (searchrl/command_line.py)
    reward: RewardConfig = field(default_factory=RewardConfig)  # reward=<name> reward.<setting>=...


# What `resume=` (and a multirun continued into its folder) may change; every other setting is the run's own.
RESUME_OVERRIDES = ("total_timesteps", "threads", "device", "progress_bar", "keep_checkpoints", "logger")


def saved_config(path: str | Path) -> DictConfig:
    """A run's saved config.yaml, upgraded to the current version (searchrl/migrations.py) and its parts' nodes
    typed (`typed_parts`, once the run's own extensions are imported, as resuming it imports them); ValueError if
    the file is no mapping."""
    from searchrl.command_line import import_modules

    loaded = OmegaConf.to_container(OmegaConf.load(path))
    if not isinstance(loaded, dict):
        raise ValueError(f"{path} holds no mapping")
    import_modules(loaded.get("extensions") or [])
    return typed_parts(OmegaConf.create(upgrade_run_config(loaded)))


def saved_run(path: Path) -> DictConfig:
    """A run's saved config.yaml (`saved_config`) merged into TrainConfig, as resuming or continuing the run trains
    with it; ConfigError in one line when the file cannot be read or does not fit the current schema (a damaged
    record; a missing extension says itself)."""
    try:
        loaded = saved_config(path)
        if loaded.get("model") is None or loaded.get("algo") is None:
            raise ValueError("it names no model or algo")
        return OmegaConf.merge(OmegaConf.structured(TrainConfig), loaded)
    except ConfigError:
        raise
    except Exception as err:  # empty, not YAML, wrong types, unreadable
        detail = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ConfigError(f"{path} does not fit the current schema or cannot be read ({detail})") from None


def _part_nodes() -> list[tuple[str, str, Any, Any, type]]:
    """(node, the setting in it that names the part, the registry, the schema of a part by name, the node's base
    dataclass) of each part a run config chooses by name."""
    return [
        ("network", "extractor", NETWORKS, network_schema, NetworkConfig),
        ("critic", "name", CRITICS, critic_schema, CriticConfig),
        ("reward", "name", REWARDS, reward_schema, RewardConfig),
    ]


def typed_parts(cfg: DictConfig) -> DictConfig:
    """`cfg` with each part's node (network, critic, reward) typed by its part's schema (`Registry.schema`): a part
    chosen by value (`network.extractor=swept_cnn` on `network=small`) gains its settings at their defaults, and a
    saved config's node merges into the schema it was made with. ConfigError naming an unregistered part."""
    for node, key, _, schema_of, base in _part_nodes():
        if isinstance(cfg.get(node), (dict, DictConfig)) and cfg[node].get(key) is not None:
            cfg[node] = typed_node(cfg[node], schema_of, base, key)
    return cfg


def run_dir(resume: str | None, model: str, seed: int, now: str) -> str:
    """Hydra's output folder: a new run under runs/train/, or, on resume, a log folder inside the resumed run."""
    return f"{resume}/resumed/{now}" if resume else f"runs/train/{model}/{now}_seed{seed}"


# Task overrides left out of a job folder's name: they change how a job runs, not what it trains.
UNNAMED = ("progress_bar", "logger", "hydra")


def job_name(num: int, overrides: list[str]) -> str:
    """`<num>_<key=value,...>`: a multirun job's number and its task overrides (Hydra's `override_dirname`, less
    UNNAMED, `+` dropped, `/` written `-`), so the folder and its TensorBoard run say what the job set, swept values
    included; e.g. `3_model=b,algo.learning_rate=0.001,seed=1`. Cut at 160 characters with a digest of the rest."""
    kept = [
        o.lstrip("+")
        for o, key in zip(overrides, override_keys(overrides), strict=True)
        if key.split(".")[0] not in UNNAMED
    ]
    name = f"{num}_{','.join(kept)}".replace("/", "-").rstrip("_")
    if len(name) > 160:
        name = f"{name[:143]}~{hashlib.sha256(name.encode()).hexdigest()[:16]}"
    return name


def job_subdir(sweep_dir: str, num: int, overrides: Any) -> str:
    """A multirun job's folder under `sweep_dir` (`hydra.sweep.subdir`): `job_name` when that folder is new or was
    made for the same overrides (a multirun continued into its folder continues its jobs: searchrl/train/
    app.py), else `<name>.1`, `<name>.2`, ... the first that is (an Optuna study continued into its folder
    numbers its new trials' jobs from 0 again: a trial of the same parameters goes beside the earlier one)."""
    wanted = [str(o) for o in overrides]
    name = job_name(int(num), wanted)
    for k in range(10_000):
        folder = name if k == 0 else f"{name}.{k}"
        saved = Path(sweep_dir) / folder / ".hydra" / "overrides.yaml"
        if not saved.is_file() or [str(o) for o in OmegaConf.load(saved)] == wanted:
            return folder
    raise RuntimeError(f"{sweep_dir}: 10,000 jobs named {name}.* with other overrides; sweep into another folder")


def root_resolver() -> str:
    """`${searchrl_root:}` in a config: the checkout (`repository_root`), so a path under it does not depend on the
    folder a command is started in."""
    return str(repository_root())


def register_configs() -> None:
    if not OmegaConf.has_resolver("searchrl_run_dir"):
        OmegaConf.register_new_resolver("searchrl_run_dir", run_dir)
    if not OmegaConf.has_resolver("searchrl_job_subdir"):
        OmegaConf.register_new_resolver("searchrl_job_subdir", job_subdir)
    if not OmegaConf.has_resolver("searchrl_root"):
        OmegaConf.register_new_resolver("searchrl_root", root_resolver)
    cs = register_shared_configs()
    cs.store(name="train_schema", node=TrainConfig)
    cs.store(group="network", name="network_schema", node=NetworkConfig)
    cs.store(group="critic", name="critic_schema", node=CriticConfig)
    # Each registered network, critic and reward is an option of its group at its settings' defaults (an
    # extension's too: the entry point runs this again once it has imported them), but where a yaml holds it
    for node, _, registry, schema_of, _ in _part_nodes():
        for name, part in registry.items():
            if part is not None and not (CONF_DIR / node / f"{name}.yaml").is_file():
                cs.store(group=node, name=name, node=schema_of(name))
    cs.store(group="logger", name="logger_schema", node=LoggerConfig)
    cs.store(group="algo", name="recurrent_ppo_schema", node=RecurrentPPOConfig)
    cs.store(group="algo", name="a2c_schema", node=A2CConfig)
