"""`SearchEnv`: the one-agent world as a plain gymnasium Env (N = 1), e.g. for single-agent baselines."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np

from searchrl.envs.parallel_env import SearchParallelEnv
from searchrl.world.config import ConfigError, WorldConfig, check_seed
from searchrl.world.scenario import PAPER, Scenario


class SearchEnv(gym.Env):
    """gymnasium view of a single-agent world; `config.n_agents` is forced to 1."""

    metadata = {"render_modes": ["rgb_array"]}  # noqa: RUF012

    def __init__(
        self, config: WorldConfig | None = None, render_mode: str | None = None, scenario: Scenario = PAPER
    ) -> None:
        if config is not None and not isinstance(config, WorldConfig):
            raise ConfigError(f"config={config!r} is not allowed: a searchrl.WorldConfig or None")
        config = replace(config if config is not None else WorldConfig(), n_agents=1)
        self._env = SearchParallelEnv(config, render_mode=render_mode, scenario=scenario)
        self._agent = self._env.possible_agents[0]
        self.render_mode = render_mode
        self.observation_space = self._env.observation_space(self._agent)
        self.action_space = self._env.action_space(self._agent)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        check_seed(seed)  # a ValueError naming it, as the other envs raise
        super().reset(seed=None if seed is None else int(seed))  # gymnasium's takes Python ints only
        # gymnasium seeds self.np_random; the world draws from its own generator, seeded from it.
        obs, infos = self._env.reset(seed=int(self.np_random.integers(2**63)))
        return obs[self._agent], infos[self._agent]

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        obs, rewards, terms, truncs, infos = self._env.step({self._agent: action})
        return obs[self._agent], rewards[self._agent], terms[self._agent], truncs[self._agent], infos[self._agent]

    def render(self) -> np.ndarray | None:
        return self._env.render()
