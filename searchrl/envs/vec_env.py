"""`SearchVecEnv`: K worlds × N agents as K·N single-agent slots of one SB3 VecEnv (parameter sharing).

Slot s is agent s % N of world s // N. A world's episode ends for all its agents at once; the world is then
reset on its own. Team metrics (L, R, F, M̄, found fraction) are reported once per world episode, in the info
of the world's first slot: `info["episode"] = {"r": R, "l": L, "t": seconds since the env was created}` (what
SB3's Monitor writes, so `rollout/ep_rew_mean` is the team return) and `info["team_metrics"]` with every metric.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.error import ResetNeeded
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from searchrl.envs.rewards import RewardFn
from searchrl.envs.spaces import action_space, observation_space
from searchrl.world.coarse import ObservationPart
from searchrl.world.config import ConfigError, WorldConfig, check_seed
from searchrl.world.engine import SearchWorld
from searchrl.world.frames import world_frames
from searchrl.world.scenario import PAPER, Scenario


class SearchVecEnv(VecEnv):
    """SB3 VecEnv over a `SearchWorld`. Attributes are shared by all slots (they live on one world), so
    `get_attr` returns the same value for every index and `set_attr` applies to all slots or raises."""

    metadata = {"render_modes": ["rgb_array"]}  # noqa: RUF012 (gymnasium convention)

    def __init__(
        self,
        config: WorldConfig,
        n_worlds: int,
        seed: int | None = None,
        render_mode: str | None = None,
        scenario: Scenario = PAPER,
        parts: Sequence[ObservationPart] = (),
        reward: RewardFn | None = None,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode={render_mode!r} is not allowed: None or 'rgb_array'")
        if not isinstance(config, WorldConfig):
            raise ConfigError(f"config={config!r} is not allowed: a searchrl.WorldConfig")
        self.config = config
        self.render_mode = render_mode
        self.world = SearchWorld(config, n_worlds, seed=seed, scenario=scenario, parts=parts)
        self.reward = reward  # searchrl/envs/rewards.py; None: the world's own
        self.n_agents = config.n_agents
        self._actions: np.ndarray | None = None
        self._t_start = time.time()
        super().__init__(n_worlds * config.n_agents, observation_space(config, parts), action_space(config))

    # --- core contract -------------------------------------------------------------------------------------
    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """SB3's: the seed of the next reset (slot i: seed + i); ValueError unless None or an integer >= 0."""
        check_seed(seed)
        return super().seed(seed)

    def reset(self) -> VecEnvObs:
        seed = self._seeds[0] if self._seeds and self._seeds[0] is not None else None
        maps, vector = self.world.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return self._flat_obs(maps, vector)

    def step_async(self, actions: np.ndarray) -> None:
        if not self.world.started:  # what gymnasium's OrderEnforcing says of an env stepped before its reset
            raise ResetNeeded("Cannot call env.step() before calling env.reset()")
        actions = np.asarray(actions)
        if actions.size != self.num_envs:
            raise ValueError(f"actions have shape {actions.shape}: one action per slot, ({self.num_envs},)")
        self._actions = actions.reshape(self.world.n_worlds, self.n_agents)  # the world checks dtype and range

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() called before step_async()")
        tr = self.world.step(self._actions)
        self._actions = None
        result = tr.result
        done_world = result.done
        dones = np.repeat(done_world, self.n_agents)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        now = round(time.time() - self._t_start, 6)
        for k in np.flatnonzero(done_world):
            bootstrap = bool(result.truncated[k] and not result.terminated[k])
            base = k * self.n_agents
            for i in range(self.n_agents):
                infos[base + i]["terminal_observation"] = {
                    "map": tr.final_maps[k, i].copy(),
                    "vector": tr.final_vector[k, i].copy(),
                    **{key: values[k, i].copy() for key, values in tr.final_parts.items()},
                }
                infos[base + i]["TimeLimit.truncated"] = bootstrap
            metrics = {name: float(values[k]) for name, values in tr.metrics.items()}
            infos[base]["team_metrics"] = metrics
            infos[base]["episode"] = {
                "r": metrics["R"],
                "l": int(metrics["L"]),
                "t": now,
            }
        obs = self._flat_obs(tr.maps, tr.vector)
        rewards = result.reward if self.reward is None else np.asarray(self.reward(self.config, result), np.float32)
        if rewards.shape != result.reward.shape:
            raise ValueError(f"the reward returned shape {rewards.shape}: one per agent, {result.reward.shape}")
        return obs, rewards.reshape(-1).copy(), dones, infos

    def _flat_obs(self, maps: np.ndarray, vector: np.ndarray) -> dict[str, np.ndarray]:
        # Copies: the world reuses its buffers, and SB3 keeps the previous observation while stepping.
        return {
            "map": maps.reshape(self.num_envs, *maps.shape[2:]).copy(),
            "vector": vector.reshape(self.num_envs, -1).copy(),
            **{key: a.reshape(self.num_envs, *a.shape[2:]).copy() for key, a in self.world.parts.items()},
        }

    def close(self) -> None:
        pass

    # --- rendering -----------------------------------------------------------------------------------------
    def get_images(self) -> Sequence[np.ndarray | None]:
        """One RGB frame per world (not per slot), padded to the largest world."""
        if self.render_mode != "rgb_array":
            raise ValueError(f"render_mode is {self.render_mode!r}; create the env with render_mode='rgb_array'")
        if not self.world.started:  # as step_async says it
            raise ResetNeeded("Cannot call env.render() before calling env.reset()")
        return world_frames(self.world.state)

    # --- attribute access (shared by all slots) ------------------------------------------------------------
    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        if len(list(self._get_indices(indices))) != self.num_envs:
            raise ValueError(
                f"set_attr({attr_name!r}) on a subset of slots is not possible: all {self.num_envs} slots share one "
                "world; pass indices=None"
            )
        setattr(self, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        """Call a method of the shared world object once and return its result for every requested slot."""
        result = getattr(self, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]
