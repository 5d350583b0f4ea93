"""A trained run's files: where its world and algorithm are recorded (`config.yaml` beside or above a checkpoint),
the name it is evaluated under, and loading its SB3 model or just its actor.

Every use of a checkpoint (evaluate, render, `init=`, `resume=`, the benches and the notebooks) loads it through
`load_checkpoint`, which unpickles nothing of the file: SB3's `load` would unpickle six or more entries of a model.zip
(its policy class, policy_kwargs, spaces and schedules), and a pickle runs whatever code its author put there. Those
entries are made again from the run's config.yaml and searchrl's code; the tensors are read with torch's weights-only
loader. So a model.zip from anyone is safe to evaluate, provided it is read this way (plain `RecurrentPPO.load` is
not safe on a file of unknown origin)."""

from __future__ import annotations

import json
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig, OmegaConf
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.utils import FloatSchedule

from searchrl.atomic import write_atomic
from searchrl.envs.spaces import action_space, observation_space
from searchrl.migrations import upgrade_run_config
from searchrl.policies.actor import Actor
from searchrl.policies.algorithms import ALGORITHMS
from searchrl.policies.networks import (
    CRITICS,
    CriticConfig,
    NetworkConfig,
    critic_schema,
    network_schema,
    observation_parts,
    policy_kwargs,
)
from searchrl.policies.recurrent import OwnCriticLstmPolicy
from searchrl.policies.slim import ROLLOUT_STATE
from searchrl.world.config import ConfigError, MissingFile, WorldConfig


def run_config(path: str | Path) -> DictConfig:
    """The run config of a checkpoint: `<run>/model.zip` or `<run>/checkpoints/step_*.zip`, next to or above which
    the run's `config.yaml` lies, read as plain YAML (OmegaConf's loader is YAML's safe one); ConfigError in one
    line naming the file (MissingFile, a FileNotFoundError too, where there is none)."""
    if not str(path).strip() or not Path(path).is_file():  # checkpoint= (empty) is Path("."), a folder
        raise MissingFile(f"checkpoint={str(path)!r} does not exist (expected a model.zip of a run)")
    path = Path(path)
    for folder in (path.parent, path.parent.parent):
        if (folder / "config.yaml").exists():
            try:
                record = OmegaConf.create(
                    upgrade_run_config(OmegaConf.to_container(OmegaConf.load(folder / "config.yaml")))
                )
                OmegaConf.select(record, "env.world", throw_on_missing=True)  # a run config has both
                str(record.algo.name)
                return record
            except Exception as err:  # not YAML, not a mapping, no env.world or algo.name: all say the same
                raise ConfigError(
                    f"checkpoint={str(path)!r}: its run's {folder / 'config.yaml'} cannot be read as a run config "
                    f"({type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}); restore the file "
                    "that searchrl.train wrote"
                ) from None
    raise MissingFile(f"checkpoint={str(path)!r} has no run config.yaml beside it or one folder up")


@dataclass(frozen=True)
class PolicyRecord:
    """What a run's policy is rebuilt from, typed: read from its config.yaml (`policy_record`) or made by a training
    plan (`Plan.policy_record`). `network` and `critic` are their parts' schemas (`network_schema`, with a
    network's own settings)."""

    algo: str
    learning_rate: float
    clip_range: float | None  # PPO's; A2C has none
    world: WorldConfig
    network: NetworkConfig
    critic: CriticConfig
    extensions: tuple[str, ...] = ()


def policy_record(record: DictConfig, path: str | Path) -> PolicyRecord:
    """The typed `PolicyRecord` of a run's config (`run_config`) for the checkpoint at `path`; ValueError in one
    line naming a part its run registered through extensions this process has not imported."""
    extensions = tuple(str(m) for m in record.get("extensions") or [])
    try:
        network = OmegaConf.to_object(typed_node(record.get("network"), network_schema, NetworkConfig, "extractor"))
        critic = OmegaConf.to_object(typed_node(record.get("critic"), critic_schema, CriticConfig, "name"))
    except ValueError as err:  # a part registered by a module this process has not imported
        hint = f"; its run had extensions={list(extensions)}: pass them here too" if extensions else ""
        raise ConfigError(f"checkpoint={str(path)!r}: its run's {err}{hint}") from None
    world = WorldConfig.from_dict(OmegaConf.to_container(record.env.world, resolve=True))
    clip = record.algo.get("clip_range")
    algo, rate = str(record.algo.name), float(record.algo.learning_rate)
    return PolicyRecord(algo, rate, None if clip is None else float(clip), world, network, critic, extensions)


def typed_node(node: DictConfig | None, schema_of: Callable[[str], type], base: type, key: str) -> DictConfig:
    """A run config's part node (`network`, `critic`, `reward`) merged into its part's schema (`schema_of` the name
    at `key`), so its settings are typed; a record made before the node or a setting existed takes the defaults."""
    values = OmegaConf.to_container(node, resolve=True) if node is not None else {}
    return OmegaConf.merge(OmegaConf.structured(schema_of(str(values.get(key, getattr(base(), key))))), values)


def checkpoint_config(path: str | Path) -> tuple[dict, str, str]:
    """(world settings, algorithm name, model name) of a checkpoint's run (`run_config`)."""
    record = run_config(path)
    model = str(record.model.name) if record.get("model") else "unknown"
    return OmegaConf.to_container(record.env.world, resolve=True), str(record.algo.name), model


def training_scenario(path: str | Path) -> dict | None:
    """The scenario mapping (`Scenario.from_dict`'s form) a checkpoint's run trained under, from its config.yaml
    (`run_config`); None when the run records none (the paper's)."""
    node = run_config(path).get("scenario")
    return None if node is None else OmegaConf.to_container(node, resolve=True)


def checkpoint_label(path: str | Path) -> str:
    """The name a checkpoint is evaluated under: its run folder's path below the nearest folder named `runs`
    (`reference/b` for the clone, `reference/term/b` for its RL policy), or the run folder's name when no `runs`
    folder holds it; `<run>@<file stem>` for any other file of the run (`reference/b@imitation`,
    `train/b/x@step_500000`). Two run folders under one `runs/` never share a label or a default output folder."""
    path = Path(path).resolve()
    run = path.parent.parent if path.parent.name == "checkpoints" else path.parent
    above = [i for i, part in enumerate(run.parts) if part == "runs"]
    name = "/".join(run.parts[above[-1] + 1 :]) if above and above[-1] < len(run.parts) - 1 else run.name
    return name if path.name == "model.zip" else f"{name}@{path.stem}"


def policy_class(algo: str, critic: CriticConfig | None = None) -> type:
    """The SB3 policy class a run of `algo` is built with: the algorithm's, or, with a critic of its own
    (`critic.name` other than shared), `OwnCriticLstmPolicy` (RecurrentPPO only)."""
    cls, policy = ALGORITHMS[algo]
    if critic is not None and CRITICS.lookup(critic.name) is not None:
        if algo != "recurrent_ppo":
            raise ConfigError(f"critic.name={critic.name!r} needs algo=recurrent_ppo (its critic LSTM), not {algo}")
        return OwnCriticLstmPolicy
    return cls.policy_aliases[policy] if isinstance(policy, str) else policy


# The entries of a model.zip's `data` that SB3 pickles (cloudpickle). Each is rebuilt from the run's config and
# searchrl's own code and handed to SB3 as a `custom_objects` replacement, so no load unpickles anything of the file:
# a pickle runs whatever code its author chose. The episode-info buffers, the rollout in progress and the rollout
# buffer's class are left empty: SB3 makes them anew (a resumed training resets its envs, as SB3's `load` with an env
# always does; `_setup_model` picks the buffer class of the observation space).
FROM_CONFIG = ("policy_class", "policy_kwargs", "observation_space", "action_space", "clip_range", "lr_schedule")
LEFT_EMPTY = (
    "ep_info_buffer",
    "ep_success_buffer",
    "_last_obs",
    "_last_original_obs",
    "_last_episode_starts",
    "rollout_buffer_class",
)
REBUILT = FROM_CONFIG + LEFT_EMPTY


def _data(path: str | Path) -> dict[str, Any]:
    """The JSON `data` member of a model.zip, read as JSON only; ConfigError in one line if the file is no SB3 zip."""
    raw = _member(path, "data")
    try:
        data = json.loads(raw) if raw is not None else None
    except ValueError:
        data = None
    if not isinstance(data, dict):
        raise ConfigError(
            f"checkpoint={str(path)!r} cannot be read as an SB3 model (no JSON data mapping); it may be "
            "truncated or not a searchrl model"
        )
    return data


def pickled_entries(path: str | Path) -> list[str]:
    """The names of the entries of a model.zip's `data` that SB3 would unpickle."""
    return [k for k, v in _data(path).items() if isinstance(v, dict) and ":serialized:" in v]


def rebuilt_entries(path: str | Path, record: PolicyRecord) -> dict[str, Any]:
    """SB3 `custom_objects` for the model.zip at `path` of a run whose record is `record`: every entry of REBUILT,
    made from `record` and searchrl's code; ConfigError in one line if the file pickles any other entry (it is not
    opened)."""
    unknown = [name for name in pickled_entries(path) if name not in REBUILT]
    if unknown:
        raise ConfigError(
            f"checkpoint={str(path)!r} holds a pickled {unknown[0]!r} entry that searchrl does not rebuild; it is "
            "refused, since unpickling a file runs whatever code it holds (a searchrl model pickles only "
            f"{', '.join(REBUILT)})"
        )
    return dict.fromkeys(LEFT_EMPTY) | {
        "policy_class": policy_class(record.algo, record.critic),
        "policy_kwargs": policy_kwargs(record.network, record.algo, record.critic),
        "observation_space": observation_space(record.world, observation_parts(record.network, record.critic)),
        "action_space": action_space(record.world),
        "clip_range": record.clip_range,  # SB3 makes it a schedule again
        "lr_schedule": FloatSchedule(record.learning_rate),  # made again from learning_rate too
    }


IDENTITY = "searchrl.json"


def save_model(model: BaseAlgorithm, path: str | Path, run: dict[str, Any], log: str | None = None) -> Path:
    """Save `model` at `path` atomically, with IDENTITY: its step, `run` (plain JSON values) and `log`, the digest
    of the run's log before that step (searchrl/train/logs.py's `log_digest`)."""
    identity = {"step": int(model.num_timesteps), "run": run, "log": log}

    def write(tmp: Path) -> None:
        model.save(tmp, exclude=list(ROLLOUT_STATE))  # no load reads the rollout in progress (LEFT_EMPTY)
        with zipfile.ZipFile(tmp, "a") as archive:
            archive.writestr(IDENTITY, json.dumps(identity, sort_keys=True))

    return write_atomic(path, write)


def _member(path: str | Path, name: str) -> bytes | None:
    """A member of the zip at `path`, None if it has none; ConfigError in one line if it is no zip."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
            twice = sorted({n for n in names if names.count(n) > 1})
            if not twice:
                return archive.read(name) if name in names else None
    except OSError:
        raise
    except Exception as err:  # BadZipFile, a truncated member
        raise ConfigError(
            f"checkpoint={str(path)!r} cannot be read as an SB3 model ({type(err).__name__}: "
            f"{str(err).splitlines()[0] if str(err) else 'no detail'}); it may be truncated or not a "
            "searchrl model"
        ) from None
    raise ConfigError(
        f"checkpoint={str(path)!r} holds the entry {twice[0]!r} twice: one copy would hide the other; not a file "
        "searchrl or SB3 wrote"
    )


def saved_identity(path: str | Path) -> dict[str, Any] | None:
    """The IDENTITY a searchrl run saved in the model.zip at `path`, None for a file without one; ValueError in one
    line if it is damaged."""
    raw = _member(path, IDENTITY)
    if raw is None:
        return None
    try:
        identity = json.loads(raw)
    except ValueError:
        identity = None
    if not isinstance(identity, dict):
        raise ConfigError(f"checkpoint={str(path)!r}: its {IDENTITY} is damaged (not a JSON mapping)")
    return identity


def saved_step(path: str | Path) -> int | None:
    """The agent-steps SB3 recorded in the model.zip at `path` (`num_timesteps` of its JSON data); None if none."""
    step = _data(path).get("num_timesteps")
    return step if isinstance(step, int) else None


def load_checkpoint(
    path: str | Path, record: PolicyRecord | None = None, cls: type[BaseAlgorithm] | None = None, **kwargs: object
) -> BaseAlgorithm:
    """The SB3 model saved at `path` by a run whose record is `record` (default: the run's own config.yaml,
    `policy_record`), loaded as `cls` (a subclass of the run's algorithm class, if given), without unpickling anything
    of the file: its pickled entries are rebuilt (`rebuilt_entries`) and its tensors read by SB3 with torch's
    weights-only loader. ConfigError in one line naming the file if it cannot be read (truncated, not an SB3 zip,
    another algorithm's or network's weights, a pickled entry searchrl does not rebuild, tensors that are not
    weights only). An OSError (no permission now, an I/O fault) passes through as it is: the file may be whole."""
    record = policy_record(run_config(path), path) if record is None else record
    algo = record.algo
    if algo not in ALGORITHMS:
        raise ConfigError(f"checkpoint={str(path)!r} was trained with algo {algo!r}; known: {sorted(ALGORITHMS)}")
    custom = rebuilt_entries(path, record)
    try:
        return (cls or ALGORITHMS[algo][0]).load(str(path), custom_objects=custom, **kwargs)
    except OSError:
        raise
    except Exception as err:  # BadZipFile, EOFError, KeyError, torch's UnpicklingError, state_dict mismatches, ...
        raise ConfigError(
            f"checkpoint={str(path)!r} cannot be read as a {algo} model of its run's config ({type(err).__name__}: "
            f"{str(err).strip().splitlines()[0] if str(err).strip() else 'no detail'}); it may be truncated, not "
            "a searchrl model, or of another network"
        ) from None


def load_actor(
    path: str | Path,
    config: WorldConfig,
    optimize: bool = True,
    device: str | torch.device = "cpu",
    inference: str = "torch",
) -> Actor:
    """The actor of a saved RecurrentPPO / PPO / A2C model.zip, its network on `device` (a checked one:
    searchrl/policies/device.py); ConfigError if it sees another field of view (channels, side) or acts in another
    action set than `config`'s world. `inference`: the extractor's path on the CPU (searchrl/policies/actor.py)."""
    # Loaded on the CPU and moved to `device` by the Actor: one path for every device.
    model = load_checkpoint(path, device="cpu")
    space = observation_space(config)
    seen, shown = model.observation_space["map"].shape, space["map"].shape
    if seen != shown:
        raise ConfigError(
            f"checkpoint={str(path)!r} sees a {seen} field of view but the world shows {shown}"
            " (channels, side, side: fov and belief_age_channel must be the checkpoint's)"
        )
    actor = Actor(model.policy, optimize=optimize, device=device, inference=inference)
    if actor.n_actions != config.n_actions:
        raise ConfigError(
            f"checkpoint={str(path)!r} acts with {actor.n_actions} actions but the world has {config.n_actions}"
        )
    return actor
