"""A multirun started again into its own folder (`hydra.sweep.dir`) continues it: each job whose folder holds a run
of the same settings is not trained again if that run finished (its score is returned, as Hydra's sweepers need),
and is resumed from its newest checkpoint if it was killed; a folder holding a run of other settings is refused
(the job fails, the others run: searchrl/multirun.py). What `resume=` may change (RESUME_OVERRIDES, say a larger
`total_timesteps`) may differ; nothing else may.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from searchrl.train.schema import RESUME_OVERRIDES, TrainConfig, saved_config
from searchrl.world.config import ConfigError
from searchrl.world.scenario import Scenario


def _flat(node: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(node, dict):
        out: dict[str, Any] = {}
        for key, value in node.items():
            out |= _flat(value, f"{prefix}{key}.")
        return out or {prefix[:-1]: {}}
    return {prefix[:-1]: node}


def _settings(cfg: DictConfig) -> dict[str, Any]:
    """The settings that decide a run, flat, its scenario as a run records it (every part written out)."""
    values = OmegaConf.to_container(cfg, resolve=True)
    values["scenario"] = Scenario.from_dict(values.get("scenario")).to_dict()
    return {k: v for k, v in _flat(values).items() if k.split(".")[0] not in (*RESUME_OVERRIDES, "resume")}


def continued_job(cfg: DictConfig, run_dir: Path, overrides: list[str]) -> tuple[DictConfig, list[str], bool]:
    """(config, overrides, finished) of a multirun job whose folder `run_dir` may hold a run already: unchanged
    with no run there; finished True for a run of these settings that reached `total_timesteps` (nothing to
    train); else the config resuming it (`resume=run_dir`) with only the changeable overrides. ConfigError for a
    run of other settings, naming the first that differs."""
    if cfg.get("resume") is not None or not (run_dir / "config.yaml").is_file():
        return cfg, overrides, False
    try:
        saved = OmegaConf.merge(OmegaConf.structured(TrainConfig), saved_config(run_dir / "config.yaml"))
    except Exception as err:  # damaged: said as resume= would say it
        raise ConfigError(f"{run_dir} holds a run whose config.yaml cannot be read ({err}); move it away") from None
    before, now = _settings(saved), _settings(cfg)
    differ = sorted(k for k in before.keys() | now.keys() if before.get(k, "<absent>") != now.get(k, "<absent>"))
    if differ:
        key = differ[0]
        raise ConfigError(
            f"{run_dir} holds a run of other settings ({key}: {before.get(key, '<absent>')} there, "
            f"{now.get(key, '<absent>')} now): sweep into another hydra.sweep.dir"
        )
    # model.zip is written once the budget is trained; its score.json is checked by the app (score.py stored_score)
    if (run_dir / "model.zip").is_file() and saved.total_timesteps == cfg.total_timesteps:
        return cfg, overrides, True
    resumed = cfg.copy()
    resumed.resume = str(run_dir)
    kept = [o for o in overrides if o.lstrip("+~").split("=")[0] in RESUME_OVERRIDES]
    return resumed, kept, False
