"""Policy rollouts on a fixed validation set: K worlds reset from one seed, one full episode each."""

from __future__ import annotations

import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm

from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld


def run_episodes(
    world_config: WorldConfig, n_worlds: int, seed: int, model: BaseAlgorithm | None, deterministic: bool = False
) -> dict[str, float]:
    """Mean episode metrics of `model` (LSTM state carried; sampled or argmax actions) or of a random walk (None)
    over n_worlds worlds drawn from `seed`; each world's first episode counts.

    Sampled actions draw from torch's global generator, forked here and seeded from `seed`: the same weights give
    the same metrics at every validation (common random numbers: a curve's steps are changes of the weights, not
    of sampling luck, which on 32 worlds moves the found fraction by a few hundredths), and the training run's
    own random stream is left as it was."""
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed + 2)
        return _run_episodes(world_config, n_worlds, seed, model, deterministic)


def _run_episodes(
    world_config: WorldConfig, n_worlds: int, seed: int, model: BaseAlgorithm | None, deterministic: bool
) -> dict[str, float]:
    world = SearchWorld(world_config, n_worlds, seed=seed)
    maps, vector = world.reset()
    n = world_config.n_agents
    act_rng = np.random.default_rng(seed + 1)
    lstm_state = None
    episode_start = np.ones(n_worlds * n, bool)
    finished = np.zeros(n_worlds, bool)
    sums: dict[str, np.ndarray] = {}
    while not finished.all():
        if model is None:
            actions = act_rng.integers(0, world_config.n_actions, size=(n_worlds, n))
        else:
            obs = {"map": maps.reshape(n_worlds * n, *maps.shape[2:]), "vector": vector.reshape(n_worlds * n, -1)}
            if world.context is not None:  # the whole-belief context (env.world.context)
                obs["context"] = world.context.reshape(n_worlds * n, *world.context.shape[2:])
            flat, lstm_state = model.predict(
                obs, state=lstm_state, episode_start=episode_start, deterministic=deterministic
            )
            actions = np.asarray(flat).reshape(n_worlds, n)
        tr = world.step(actions)
        maps, vector = tr.maps, tr.vector
        first = tr.result.done & ~finished
        for name, values in tr.metrics.items():
            sums[name] = sums.get(name, np.zeros(n_worlds)) + np.where(first, values, 0.0)
        finished |= tr.result.done
        episode_start = np.repeat(tr.result.done, n)
    return {name: float(v.mean()) for name, v in sums.items()}
