"""Hydra schemas shared by the training and evaluation apps: the env group (the world's settings and its teams),
the model presets and the scenario, registered in the ConfigStore; and how a command line's overrides name keys.

conf/env      -> EnvConfig    (world: WorldConfig's fields, the engine's own validated dataclass)
conf/model    -> ModelConfig  (a model preset also writes Φ, communication, actions into env.world)
conf/scenario -> a plain mapping read by searchrl.world.scenario.Scenario.from_dict
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, make_dataclass
from typing import Any, get_type_hints

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf

from searchrl.world.config import WorldConfig

# WorldConfig's fields as a Hydra schema: the same names, types and defaults (types and unknown keys are checked at
# composition), but `world_size` untyped so that an integer (`env.world.world_size=20`, every world 20×20) composes
# as well as a range `[20, 128]`. WorldConfig itself checks every value again when the run builds it.
WorldSchema = make_dataclass(
    "WorldSchema",
    [(f.name, Any if f.name == "world_size" else get_type_hints(WorldConfig)[f.name], field(default=f.default))
     for f in fields(WorldConfig)],
)  # fmt: skip
WorldSchema.__module__ = __name__  # pickled by reference (submitit unpickles configs)


def _world_node() -> DictConfig:
    """WorldSchema as a typed node."""
    return OmegaConf.structured(WorldSchema)


@dataclass
class TeamConfig:
    n_agents: int = MISSING  # N of this group's worlds
    n_worlds: int = MISSING  # K of this group
    # [n_min, n_max] of this group's worlds, or n (every world n×n); null keeps env.world.world_size. Lets a clone
    # see the crowded large worlds of the evaluation grid (n = 160, N = 256) that the training range [20, 128] never
    # holds. Untyped so that both forms compose; WorldConfig checks it.
    world_size: Any = None


@dataclass
class EnvConfig:
    world: Any = field(default_factory=_world_node)
    n_worlds: int = 16  # K worlds per VecEnv: K·N slots share the policy
    # More groups of worlds with other team sizes in the same rollout (`TeamMixVecEnv`), e.g.
    # 'env.extra_teams=[{n_agents:32,n_worlds:4},{n_agents:128,n_worlds:1,world_size:[80,160]}]'. Empty (the
    # paper): every world has env.world.n_agents.
    extra_teams: list[TeamConfig] = field(default_factory=list)
    # Every group's K worlds (env.n_worlds and each extra team's) taken this many times: slots per step and the
    # rollout grow by the factor, the team mix stays. For machines with many cores or a GPU (conf/machine/).
    replicas: int = 1


@dataclass
class ModelConfig:
    name: str = MISSING  # a, b, c, diagonal (trainable) or a heuristic (surfing, coverage, random)
    trainable: bool = True


MAX_THREADS = 1024  # torch's intra-op threads: far more than any node's cores; refused before the folder lock


def scenario_default() -> dict[str, Any]:
    """Empty: the defaults list's scenario file (conf/scenario/paper.yaml unless `scenario=` names another) fills
    the node whole. A schema default would merge its settings into every other file's parts (a maze's obstacles
    would keep iid's `density`); an empty mapping reads as the paper's (`Scenario.from_dict`)."""
    return {}


def override_keys(overrides: list[str]) -> list[str]:
    """The keys a command line's Hydra overrides set: `+a.b=1`, `~a.b`, `a.b=1` -> `a.b`."""
    return [o.split("=", 1)[0].lstrip("+~") for o in overrides]


def register_shared_configs() -> ConfigStore:
    """Store the shared groups' schemas; returns the ConfigStore for the app's own."""
    cs = ConfigStore.instance()
    cs.store(group="env", name="env_schema", node=EnvConfig)
    cs.store(group="model", name="model_schema", node=ModelConfig)
    return cs
