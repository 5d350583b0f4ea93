"""A trained run's files: where its world and algorithm are recorded (`config.yaml` beside or above a checkpoint),
the name it is evaluated under, and loading its SB3 model or just its actor, old checkpoints included."""

from __future__ import annotations

from pathlib import Path

import torch
from omegaconf import OmegaConf
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.save_util import load_from_zip_file

from searchrl.envs.spaces import observation_space
from searchrl.policies.actor import Actor
from searchrl.policies.algorithms import ALGORITHMS
from searchrl.world.config import WorldConfig


def checkpoint_config(path: str | Path) -> tuple[dict, str, str]:
    """(world settings, algorithm name, model name) from the run directory of a checkpoint: `<run>/model.zip` or
    `<run>/checkpoints/step_*.zip`, next to or above which the run's `config.yaml` lies."""
    if not str(path).strip() or not Path(path).is_file():  # checkpoint= (empty) is Path("."), a folder
        raise FileNotFoundError(f"checkpoint={str(path)!r} does not exist (expected a model.zip of a run)")
    path = Path(path)
    for folder in (path.parent, path.parent.parent):
        if (folder / "config.yaml").exists():
            try:
                cfg = OmegaConf.load(folder / "config.yaml")
                model = str(cfg.model.name) if cfg.get("model") else "unknown"
                return OmegaConf.to_container(cfg.env.world, resolve=True), str(cfg.algo.name), model
            except Exception as err:  # not YAML, not a mapping, no env.world or algo.name: all say the same
                raise ValueError(
                    f"checkpoint={str(path)!r}: its run's {folder / 'config.yaml'} cannot be read as a run config "
                    f"({type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}); restore the file "
                    "that searchrl.train wrote"
                ) from None
    raise FileNotFoundError(f"checkpoint={str(path)!r} has no run config.yaml beside it or one folder up")


def training_scenario(path: str | Path) -> dict | None:
    """The scenario mapping (`Scenario.from_dict`'s form) a checkpoint's run trained under, from its config.yaml
    (`checkpoint_config` finds and checks it); None when the run records none (the paper's)."""
    path = Path(path)
    for folder in (path.parent, path.parent.parent):
        if (folder / "config.yaml").exists():
            node = OmegaConf.load(folder / "config.yaml").get("scenario")
            return None if node is None else OmegaConf.to_container(node, resolve=True)
    return None


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


def load_checkpoint(path: str | Path, algo: str, cls: type[BaseAlgorithm] | None = None,
                    **kwargs: object) -> BaseAlgorithm:  # fmt: skip
    """The SB3 model saved at `path` by algorithm `algo` (loaded as `cls`, a subclass of that algorithm's class, if
    given); ValueError naming the file if what it holds cannot be read (truncated, not an SB3 zip, another
    algorithm's). An OSError (no permission now, an I/O fault) passes through as it is: the file may be whole."""
    if algo not in ALGORITHMS:
        raise ValueError(f"checkpoint={str(path)!r} was trained with algo {algo!r}; known: {sorted(ALGORITHMS)}")
    try:
        custom = retired_kwargs_dropped(path) or {}
        if isinstance(ALGORITHMS[algo][1], type):  # checkpoints saved with sb3-contrib's own class load as this one
            custom["policy_class"] = ALGORITHMS[algo][1]
        return (cls or ALGORITHMS[algo][0]).load(str(path), custom_objects=custom, **kwargs)
    except OSError:
        raise
    except Exception as err:  # BadZipFile, EOFError, KeyError, RuntimeError of torch.load, ...
        raise ValueError(
            f"checkpoint={str(path)!r} cannot be read as a {algo} model ({type(err).__name__}: "
            f"{str(err).splitlines()[0] if str(err) else 'no detail'}); it may be truncated or not a searchrl model"
        ) from None


# Keyword arguments of the features extractor removed since some checkpoints were saved (the whole-belief context
# stream's widths, inert without a context observation): a checkpoint holding them loads without them.
RETIRED_EXTRACTOR_KWARGS = ("context_channels", "context_size")


def retired_kwargs_dropped(path: str | Path) -> dict | None:
    """SB3 `custom_objects` replacing a checkpoint's policy_kwargs by the same without RETIRED_EXTRACTOR_KWARGS, or
    None when it has none of them."""
    data, _, _ = load_from_zip_file(str(path), load_data=True, device="cpu")
    kwargs = dict((data or {}).get("policy_kwargs") or {})
    extractor = dict(kwargs.get("features_extractor_kwargs") or {})
    if not any(name in extractor for name in RETIRED_EXTRACTOR_KWARGS):
        return None
    kwargs["features_extractor_kwargs"] = {k: v for k, v in extractor.items() if k not in RETIRED_EXTRACTOR_KWARGS}
    return {"policy_kwargs": kwargs}


def load_actor(path: str | Path, config: WorldConfig, optimize: bool = True,
               device: str | torch.device = "cpu") -> Actor:  # fmt: skip
    """The actor of a saved RecurrentPPO / PPO / A2C model.zip, its network on `device` (a checked one:
    searchrl/policies/device.py); ValueError if it sees another field of view (channels, side) or acts in another
    action set than `config`'s world."""
    _, algo, _ = checkpoint_config(path)
    # Loaded on the CPU and moved to `device` by the Actor: one path for every device.
    model = load_checkpoint(path, algo, device="cpu")
    space = observation_space(config)
    seen, shown = model.observation_space["map"].shape, space["map"].shape
    if seen != shown:
        raise ValueError(
            f"checkpoint={str(path)!r} sees a {seen} field of view but the world shows {shown}"
            " (channels, side, side: fov and belief_age_channel must be the checkpoint's)"
        )
    actor = Actor(model.policy, optimize=optimize, device=device)
    if actor.n_actions != config.n_actions:
        raise ValueError(
            f"checkpoint={str(path)!r} acts with {actor.n_actions} actions but the world has {config.n_actions}"
        )
    return actor
