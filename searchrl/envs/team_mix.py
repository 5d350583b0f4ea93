"""`TeamMixVecEnv`: several `SearchVecEnv`s with different team sizes N as one SB3 VecEnv.

The paper trains with N = 8 only (§4.1.2); a policy trained so has never been in a crowd of 32-256 agents. Mixing
team sizes in one rollout lets the one shared policy learn both regimes. Slots are laid out group after group:
the slots of group 0 (K₀·N₀ of them, as in `SearchVecEnv`), then group 1, and so on. Every group has the same
observation and action spaces (they depend on Φ, fov and the action set, not on N).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from searchrl.envs.vec_env import SearchVecEnv
from searchrl.world.config import ConfigError


class TeamMixVecEnv(VecEnv):
    """The slots of `envs` concatenated. Seeding with `seed(s)` seeds group j with s + j."""

    def __init__(self, envs: Sequence[SearchVecEnv]) -> None:
        if len(envs) < 1:
            raise ConfigError("envs=[] is not allowed: give at least one SearchVecEnv")
        first = envs[0]
        for j, env in enumerate(envs[1:], start=1):
            if env.observation_space != first.observation_space or env.action_space != first.action_space:
                raise ValueError(
                    f"envs[{j}] has other observation or action spaces than envs[0]: same Φ, fov and action set needed"
                )
        self.envs = list(envs)
        self.render_mode = first.render_mode
        self._bounds = np.cumsum([0] + [env.num_envs for env in self.envs])  # group j owns slots [b_j, b_j+1)
        super().__init__(int(self._bounds[-1]), first.observation_space, first.action_space)

    def reset(self) -> VecEnvObs:
        base = self._seeds[0] if self._seeds and self._seeds[0] is not None else None
        if base is not None:
            for j, env in enumerate(self.envs):
                env.seed(base + j)
        observations = [env.reset() for env in self.envs]
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return _concat(observations)

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        for j, env in enumerate(self.envs):
            env.step_async(actions[self._bounds[j] : self._bounds[j + 1]])

    def step_wait(self) -> VecEnvStepReturn:
        results = [env.step_wait() for env in self.envs]
        obs = _concat([r[0] for r in results])
        rewards = np.concatenate([r[1] for r in results])
        dones = np.concatenate([r[2] for r in results])
        infos = [info for r in results for info in r[3]]
        return obs, rewards, dones, infos

    def close(self) -> None:
        for env in self.envs:
            env.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        """One frame per world of every group."""
        return [frame for env in self.envs for frame in env.get_images()]

    # --- attribute access: per slot, answered by the slot's group ------------------------------------------
    def _group(self, slot: int) -> SearchVecEnv:
        return self.envs[int(np.searchsorted(self._bounds, slot, side="right")) - 1]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self._group(i), attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        if len(list(self._get_indices(indices))) != self.num_envs:
            raise ValueError(
                f"set_attr({attr_name!r}) on a subset of slots is not possible: slots share worlds; pass indices=None"
            )
        for env in self.envs:
            env.set_attr(attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        """Call the method once per group and return each slot its group's result."""
        results = [getattr(env, method_name)(*method_args, **method_kwargs) for env in self.envs]
        return [results[int(np.searchsorted(self._bounds, i, side="right")) - 1] for i in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]


def _concat(observations: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {key: np.concatenate([obs[key] for obs in observations]) for key in observations[0]}
