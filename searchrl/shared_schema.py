"""The config both apps share: where it lives (conf/ beside the package: the one place the repository root is
computed), the Hydra schemas of the env group (the world's settings and its teams), the model presets and the
scenario, registered in the ConfigStore; and how a command line's overrides name keys.

conf/env      -> EnvConfig    (world: WorldConfig's fields, the engine's own validated dataclass)
conf/model    -> ModelConfig  (a model preset also writes Φ, communication, actions into env.world)
conf/scenario -> a plain mapping read by searchrl.world.scenario.Scenario.from_dict
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, fields, is_dataclass, make_dataclass
from difflib import get_close_matches
from pathlib import Path
from typing import Any, get_type_hints

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, ListConfig, OmegaConf, ValueNode

from searchrl.world.config import ConfigError, WorldConfig


def repository_root() -> Path:
    """The checkout searchrl runs from: the folder holding `searchrl/` and `conf/`."""
    return Path(__file__).resolve().parents[1]


CONF_DIR = repository_root() / "conf"  # Hydra's config folder of every app


def group_options(group: str) -> list[str]:
    """The options of config group `group`: conf/<group>/**/*.yaml as `<group>=` names them (`term/b`)."""
    folder = CONF_DIR / group
    return sorted(p.relative_to(folder).with_suffix("").as_posix() for p in folder.rglob("*.yaml"))


def recipes() -> list[str]:
    """The training recipes, `+experiment=<name>`: conf/experiment/<name>.yaml, subfolders by what they make
    (`term/b` makes runs/reference/term/b, `clone/b` the clone runs/reference/b; `research/` ships nothing)."""
    return group_options("experiment")


# WorldConfig's fields as a Hydra schema: the same names, types and defaults (types and unknown keys are checked at
# composition), but `world_size` untyped so that an integer (`env.world.world_size=20`, every world 20×20) composes
# as well as a range `[20, 128]`. WorldConfig itself checks every value again when the run builds it.
WorldSchema = make_dataclass(
    "WorldSchema",
    [
        (f.name, Any if f.name == "world_size" else get_type_hints(WorldConfig)[f.name], field(default=f.default))
        for f in fields(WorldConfig)
    ],
)
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


def check_world_node(env: EnvConfig) -> None:
    """ConfigError unless `env.world` holds the world's settings (its node is untyped: `env.world=5` composes)."""
    if not is_dataclass(env.world):
        raise ConfigError(
            f"env.world={env.world!r} is not allowed: the world's settings, each set as env.world.<name>=<value>"
        )


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
    name: str = MISSING  # a, b, c or diagonal: conf/model/<name>.yaml


TRAINABLE_MODELS = ("a", "b", "c", "diagonal")  # the files of conf/model/
MAX_THREADS = 1024  # torch's intra-op threads: far more than any node's cores; refused before the folder lock


def check_threads(threads: int) -> None:
    """`threads=` of an app: 1 to MAX_THREADS; ConfigError naming it."""
    if not 1 <= threads <= MAX_THREADS:
        raise ConfigError(f"threads={threads!r} is not allowed: 1 <= threads <= {MAX_THREADS} (torch threads)")


def scenario_default() -> dict[str, Any]:
    """Empty: the defaults list's scenario file (conf/scenario/paper.yaml unless `scenario=` names another) fills
    the node whole. A schema default would merge its settings into every other file's parts (a maze's obstacles
    would keep iid's `density`); an empty mapping reads as the paper's (`Scenario.from_dict`)."""
    return {}


def nearest(word: str, options: list[str], prefix: str = "") -> str:
    """` (did you mean <prefix><option>?)` for the option closest to a misspelt `word`, or "" where none is close."""
    near = get_close_matches(word, options, n=1, cutoff=0.6)
    return f" (did you mean {prefix}{near[0]}?)" if near else ""


def dotted_leaves(tree: Any, prefix: str = "", keep_empty: bool = False) -> dict[str, Any]:
    """{dotted key: value} of a nested mapping, as a command line names its settings (lists are values); an empty
    mapping leaves no key, or with `keep_empty` is a value of its own ({})."""
    if not isinstance(tree, dict) or (keep_empty and prefix and not tree):
        return {prefix: tree}
    out: dict[str, Any] = {}
    for key, value in tree.items():
        out |= dotted_leaves(value, f"{prefix}.{key}" if prefix else str(key), keep_empty)
    return out


def override_keys(overrides: list[str]) -> list[str]:
    """The keys a command line's Hydra overrides set: `+a.b=1`, `~a.b`, `a.b=1` -> `a.b`."""
    return [o.split("=", 1)[0].lstrip("+~") for o in overrides]


def unknown_keys(cfg: DictConfig) -> list[str]:
    """The keys of `cfg` that no schema knows, each as `key[=value] is not allowed: no such setting (did you mean
    near?)`: a node typed by a dataclass (its schema) holds only that dataclass's fields, and `+key=value` on the
    command line adds one Hydra does not refuse. Nodes typed as plain mappings (a scenario, a teacher's arguments)
    are their readers' to check. Lists of typed nodes (`env.extra_teams`) are walked too."""
    found: list[str] = []

    def walk(node: Any, path: str) -> None:
        if isinstance(node, ListConfig):
            for index in range(len(node)):
                walk(node._get_node(index), f"{path}[{index}]")
            return
        if not isinstance(node, DictConfig) or node._is_none() or node._is_missing():
            return
        schema = OmegaConf.get_type(node)
        known = [f.name for f in fields(schema)] if is_dataclass(schema) else None
        for key in node:
            name = f"{path}.{key}" if path else str(key)
            if known is not None and key not in known:
                value = node._get_node(key)
                shown = f"{name}={value._value()!r}" if isinstance(value, ValueNode) else name
                hint = nearest(str(key), known, f"{path}." if path else "")
                found.append(f"{shown} is not allowed: no such setting{hint}")
                continue
            walk(node._get_node(key), name)

    walk(cfg, "")
    return found


def check_known_keys(cfg: DictConfig) -> None:
    """Raise ConfigError naming every key of `cfg` that no schema knows (`unknown_keys`), in one line."""
    unknown = unknown_keys(cfg)
    if unknown:
        raise ConfigError(
            f"{'; '.join(unknown)} (docs/options.md lists the settings; Hydra adds a key given with '+' without a word)"
        )


def register_shared_configs() -> ConfigStore:
    """Store the shared groups' schemas; returns the ConfigStore for the app's own."""
    cs = ConfigStore.instance()
    cs.store(group="env", name="env_schema", node=EnvConfig)
    cs.store(group="model", name="model_schema", node=ModelConfig)
    return cs


def _compose(config_name: str, group: str) -> DictConfig:
    """conf/<config_name>.yaml composed on its own, in the running app's (or test's) search path if Hydra is
    initialised, else in conf/; ConfigError names an option of `group` that does not exist."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.errors import MissingConfigException

    def composed() -> DictConfig:
        try:
            with warnings.catch_warnings():  # a group file composed as a primary config: Hydra asks for `_self_`
                warnings.filterwarnings("ignore", message=".*Defaults list is missing `_self_`")
                return compose(config_name=config_name)
        except MissingConfigException:
            options = ", ".join(group_options(group))
            raise ConfigError(
                f"{group}={config_name.split('/', 1)[1]} does not exist; conf/{group}/ has {options}"
            ) from None

    if GlobalHydra.instance().is_initialized():
        return composed()
    with initialize_config_dir(str(CONF_DIR), version_base="1.3"):
        return composed()


def group_option(group: str, name: str) -> dict[str, Any]:
    """conf/<group>/<name>.yaml as Hydra composes it (its defaults list applied: a suite's families come from
    conf/families/), a plain mapping; for readers outside an app (render, notebooks, tests). ConfigError names an
    option that does not exist."""
    return OmegaConf.to_container(_compose(f"{group}/{name}", group)[group], resolve=True)


def model_world(name: str) -> dict[str, Any]:
    """The world settings (`env.world`) of conf/model/<name>.yaml, one of the trainable models (a, b, c,
    diagonal), a plain mapping; ConfigError names a model that does not exist or sets none (a heuristic's)."""
    register_shared_configs()
    world = OmegaConf.to_container(_compose(f"model/{name}", "model"), resolve=True).get("env", {}).get("world")
    if not world:
        raise ConfigError(f"model={name} sets no world (env.world): use {', '.join(TRAINABLE_MODELS)}")
    return world
