"""The controller interface shared by trained policies and heuristics."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from searchrl.world.config import WorldConfig
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams, random_source


class Controller(Protocol):
    """Acts for all agents of K worlds at once.

    `reset(state, mask)` is called after the worlds in `mask` (K,) were reset (all of them at the start), so
    per-world memory (an LSTM state, a sweep plan) starts afresh there. `act` returns (K, N) int64 actions in
    [0, config.n_actions) from the state and the agents' observations maps (K, N, C, F, F), C = 5, or 6 with
    `belief_age_channel`, and vector (K, N, 3).
    `active` (K,) bool, when given, marks the worlds whose actions count; a controller may skip the others
    (an expensive policy does; the heuristics act everywhere so their random draws do not depend on it).
    Decentralised controllers read only what an agent may know: its observation, its own belief and position.
    A rule with memory of its own may also have `copy_memory(into, index, agents)`, which a planner calls to give
    its imagined worlds' copy of the rule that memory (searchrl/controllers/greedy.py).
    """

    config: WorldConfig

    def reset(self, state: WorldState, mask: np.ndarray) -> None: ...

    def act(
        self, state: WorldState, maps: np.ndarray, vector: np.ndarray, active: np.ndarray | None = None
    ) -> np.ndarray: ...


@dataclass
class ControllerConfig:
    """Settings of a heuristic controller (`controller=<name>`, `imitation.teacher=<name>`): one dataclass beside each
    controller's class, its fields the class's keyword arguments; `name` is its key in
    `searchrl.controllers.registry.HEURISTICS`."""

    name: str = "???"  # omegaconf's MISSING: a schema composes only with its name set


@dataclass
class RandomConfig(ControllerConfig):
    name: str = "random"


class RandomWalk:
    """Uniformly random actions: the floor every controller should beat."""

    def __init__(self, config: WorldConfig, seed: int | WorldStreams = 0) -> None:
        self.config = config
        self.rng = random_source(seed)

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        pass

    def act(
        self, state: WorldState, maps: np.ndarray, vector: np.ndarray, active: np.ndarray | None = None
    ) -> np.ndarray:
        return self.rng.integers(0, self.config.n_actions, size=(state.n_worlds, state.n_agents))


class FallbackHeuristic(RandomWalk):
    """Shell of the compiled heuristics (surfing, greedy): a kernel fills the (K, N) actions from the state, and
    agents with nothing to follow take a uniformly random move (never stay), drawn as the random walk draws."""

    def act(
        self, state: WorldState, maps: np.ndarray, vector: np.ndarray, active: np.ndarray | None = None
    ) -> np.ndarray:
        k, n = state.n_worlds, state.n_agents
        fallback = self.rng.integers(1, self.config.n_actions, size=(k, n))
        out = np.empty((k, n), np.int64)
        self.fill(state, fallback, out)
        return out

    def fill(self, state: WorldState, fallback: np.ndarray, out: np.ndarray) -> None:
        """out (K, N) int64 <- actions; fallback (K, N) holds the random moves for agents with nothing to follow."""
        raise NotImplementedError
