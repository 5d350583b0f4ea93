"""`SearchWorld`: K worlds × N agents with auto-reset. The one object the env layers wrap."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from searchrl.world.config import WorldConfig, check_seed, is_int, need
from searchrl.world.context import context_buffer, observe_context
from searchrl.world.metrics import episode_metrics
from searchrl.world.observe import observation_buffers, observe
from searchrl.world.reset import reset_worlds
from searchrl.world.state import WorldState, allocate
from searchrl.world.step import StepResult, step


@dataclass
class Transition:
    """What `SearchWorld.step` returns. Observations are those after auto-reset for finished worlds;
    `final_maps`/`final_vector` hold the last observation of the worlds that finished (others are stale)."""

    maps: np.ndarray  # (K, N, C, fov, fov) float32, C = 5, or 6 with belief_age_channel
    vector: np.ndarray  # (K, N, 3) float32
    result: StepResult
    final_maps: np.ndarray  # (K, N, C, fov, fov) float32, valid where result.done
    final_vector: np.ndarray  # (K, N, 3) float32, valid where result.done
    metrics: dict[str, np.ndarray]  # (K,) each, episode metrics, valid where result.done
    context: np.ndarray | None = None  # (K, N, 3, G, G) float32 with `config.context` (world/context.py), else None
    final_context: np.ndarray | None = None  # (K, N, 3, G, G) float32, valid where result.done; None when off


class SearchWorld:
    """K independent worlds stepped together; a finished world is reset on its own, others untouched.

    All randomness comes from one `np.random.Generator` seeded at construction or by `reset(seed)`.
    """

    def __init__(self, config: WorldConfig, n_worlds: int, seed: int | None = None) -> None:
        need(is_int(n_worlds) and n_worlds >= 1, "n_worlds", n_worlds, "an integer >= 1")
        check_seed(seed)
        self.config = config
        self.state: WorldState = allocate(config, n_worlds)
        self.rng = np.random.default_rng(seed)
        self._obs = observation_buffers(config, n_worlds)
        self._final = tuple(np.zeros_like(a) for a in self._obs)
        self._context = context_buffer(config, n_worlds)  # None when the context is off: nothing computed
        self._final_context = None if self._context is None else np.zeros_like(self._context)
        self.context: np.ndarray | None = None  # the context observed with the last reset or step

    @property
    def n_worlds(self) -> int:
        return self.state.n_worlds

    def reset(self, seed: int | None = None, mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Reset the worlds in `mask` (all by default); `seed` reseeds the generator first."""
        if seed is not None:
            check_seed(seed)
            self.rng = np.random.default_rng(seed)
        mask = np.ones(self.n_worlds, bool) if mask is None else np.asarray(mask, bool)
        reset_worlds(self.config, self.state, mask, self.rng)
        self.context = observe_context(self.config, self.state, self._context)
        return observe(self.config, self.state, self._obs)

    def step(self, actions: np.ndarray) -> Transition:
        """Step all worlds with actions (K, N), then reset the finished ones."""
        result = step(self.config, self.state, actions, self.rng)
        maps, vector = observe(self.config, self.state, self._obs)
        context = observe_context(self.config, self.state, self._context)
        done = result.done
        metrics: dict[str, np.ndarray] = {}
        if done.any():
            self._final[0][done] = maps[done]
            self._final[1][done] = vector[done]
            if context is not None:
                self._final_context[done] = context[done]
            metrics = episode_metrics(self.state)
            reset_worlds(self.config, self.state, done, self.rng)
            maps, vector = observe(self.config, self.state, self._obs)
            context = observe_context(self.config, self.state, self._context)
        self.context = context
        return Transition(maps, vector, result, self._final[0], self._final[1], metrics, context, self._final_context)
