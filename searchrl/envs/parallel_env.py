"""`SearchParallelEnv`: one search world as a PettingZoo ParallelEnv, for RLlib, TorchRL, BenchMARL users.

It wraps the batched engine's `SearchWorld` with K = 1 (same step, observations and metrics; no auto-reset). All
agents act at once and the episode ends for all of them together; then `agents` is empty until the next `reset`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from searchrl.envs.spaces import action_space, observation_space
from searchrl.world.coarse import ObservationPart
from searchrl.world.config import ConfigError, WorldConfig, check_seed, is_int
from searchrl.world.engine import SearchWorld
from searchrl.world.frames import world_frame
from searchrl.world.scenario import PAPER, Scenario
from searchrl.world.state import WorldState

AgentID = str


class SearchParallelEnv(ParallelEnv):
    """PettingZoo parallel API over one world. `config` fixes the model (Φ, communication, actions); `parts`
    (searchrl/envs/parts.py, e.g. `make_parts([("own_map", {})])`) are observed beside the window and the vector."""

    metadata = {"name": "searchrl_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}  # noqa: RUF012

    def __init__(
        self,
        config: WorldConfig | None = None,
        render_mode: str | None = None,
        scenario: Scenario = PAPER,
        parts: Sequence[ObservationPart] = (),
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode={render_mode!r} is not allowed: None or 'rgb_array'")
        if config is not None and not isinstance(config, WorldConfig):
            raise ConfigError(f"config={config!r} is not allowed: a searchrl.WorldConfig or None")
        self.config = config if config is not None else WorldConfig()
        self.world = SearchWorld(self.config, 1, scenario=scenario, auto_reset=False, parts=parts)
        self.render_mode = render_mode
        self.possible_agents: list[AgentID] = [f"agent_{i}" for i in range(self.config.n_agents)]
        self.agents: list[AgentID] = []
        self._observation_space = observation_space(self.config, parts)
        self._action_space = action_space(self.config)

    @property
    def world_state(self) -> WorldState:
        """The state of the one world (`SearchWorld.state`, K = 1)."""
        return self.world.state

    def observation_space(self, agent: AgentID) -> spaces.Dict:
        self._check_agent(agent)
        return self._observation_space

    def action_space(self, agent: AgentID) -> spaces.Discrete:
        self._check_agent(agent)
        return self._action_space

    def _check_agent(self, agent: AgentID) -> None:
        if agent not in self.possible_agents:
            last = len(self.possible_agents) - 1
            raise ConfigError(f"agent={agent!r} is not allowed: one of possible_agents, agent_0 … agent_{last}")

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        check_seed(seed)  # ConfigError, a ValueError
        maps, vector = self.world.reset(seed=seed)
        self.agents = list(self.possible_agents)
        return self._observations(maps, vector), {agent: {} for agent in self.agents}

    def step(self, actions: dict[AgentID, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("step() called before reset() or after the episode ended: call reset() first")
        if not isinstance(actions, dict):
            raise ConfigError(f"actions={actions!r} is not allowed: a dict {{agent name: action}}")
        missing = [agent for agent in self.agents if agent not in actions]
        if missing:
            raise KeyError(f"actions missing for {missing}: every live agent acts at every step")
        unknown = [agent for agent in actions if agent not in self.agents]
        if unknown:
            raise ConfigError(f"actions for {unknown} are not allowed: the live agents are {self.agents}")
        n = self.config.n_actions
        for agent in self.agents:
            a = actions[agent]
            if not (is_int(a) or (isinstance(a, np.ndarray) and a.shape == () and is_int(a[()]))) or not 0 <= a < n:
                raise ConfigError(f"actions[{agent!r}]={a!r} is not allowed: an integer in [0, {n})")
        joint = np.array([[int(actions[agent]) for agent in self.possible_agents]], np.int64)
        transition = self.world.step(joint)
        result = transition.result
        obs = self._observations(transition.maps, transition.vector)
        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0])
        rewards = {agent: float(result.reward[0, i]) for i, agent in enumerate(self.agents)}
        infos: dict[AgentID, dict] = {agent: {} for agent in self.agents}
        if terminated or truncated:
            metrics = {name: float(v[0]) for name, v in transition.metrics.items()}
            for agent in self.agents:
                infos[agent]["team_metrics"] = metrics
        terminations = {agent: terminated for agent in self.agents}
        truncations = {agent: truncated for agent in self.agents}
        if terminated or truncated:
            self.agents = []
        return obs, rewards, terminations, truncations, infos

    def _observations(self, maps: np.ndarray, vector: np.ndarray) -> dict[AgentID, dict[str, np.ndarray]]:
        return {
            agent: {
                "map": maps[0, i].copy(),
                "vector": vector[0, i].copy(),
                **{key: values[0, i].copy() for key, values in self.world.parts.items()},
            }
            for i, agent in enumerate(self.possible_agents)
        }

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if not self.world.started:
            raise RuntimeError("render() called before reset(): call reset() first")
        return world_frame(self.world_state, 0)

    def close(self) -> None:
        pass
