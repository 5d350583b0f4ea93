"""A trained SB3 policy as a batched controller, its recurrent state carried across steps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from searchrl.world.config import WorldConfig
from searchrl.world.state import WorldState


def checkpoint_config(path: str | Path) -> tuple[dict, str, str]:
    """(world settings, algorithm name, model name) from the run directory of a checkpoint: `<run>/model.zip` or
    `<run>/checkpoints/step_*.zip`, next to or above which the run's `config.yaml` lies."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint={str(path)!r} does not exist (expected a model.zip of a run)")
    for folder in (path.parent, path.parent.parent):
        if (folder / "config.yaml").exists():
            cfg = OmegaConf.load(folder / "config.yaml")
            model = str(cfg.model.name) if cfg.get("model") else "unknown"
            return OmegaConf.to_container(cfg.env.world, resolve=True), str(cfg.algo.name), model
    raise FileNotFoundError(f"checkpoint={str(path)!r} has no run config.yaml beside it or one folder up")


class PolicyController:
    """Acts with a saved RecurrentPPO / PPO / A2C model; `deterministic=False` samples from the policy."""

    def __init__(self, path: str | Path, config: WorldConfig, deterministic: bool = False, device: str = "cpu"):
        from searchrl.train.build import ALGORITHMS  # torch and SB3 only when a policy is used

        _, algo, _ = checkpoint_config(path)
        algo_class, _ = ALGORITHMS[algo]
        self.model = algo_class.load(str(path), device=device)
        expected = self.model.action_space.n
        if expected != config.n_actions:
            raise ValueError(f"checkpoint acts with {expected} actions but the world has {config.n_actions}")
        self.config = config
        self.deterministic = deterministic
        self.recurrent = algo == "recurrent_ppo"
        self._lstm = None
        self._start: np.ndarray | None = None

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        n = state.n_agents
        if self._start is None or self._start.shape[0] != state.n_worlds * n:
            self._start = np.ones(state.n_worlds * n, bool)
            self._lstm = None
        self._start |= np.repeat(np.asarray(mask, bool), n)

    def act(self, state: WorldState, maps: np.ndarray, vector: np.ndarray) -> np.ndarray:
        k, n = state.n_worlds, state.n_agents
        obs = {"map": maps.reshape(k * n, *maps.shape[2:]), "vector": vector.reshape(k * n, -1)}
        if self.recurrent:
            actions, self._lstm = self.model.predict(
                obs, state=self._lstm, episode_start=self._start, deterministic=self.deterministic
            )
        else:
            actions, _ = self.model.predict(obs, deterministic=self.deterministic)
        self._start[:] = False
        return np.asarray(actions, np.int64).reshape(k, n)
