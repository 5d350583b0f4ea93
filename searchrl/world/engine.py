"""`SearchWorld`: K worlds × N agents, the one sequencing of a world step (step, observe, episode metrics, reset of
the finished worlds) that every env layer and episode runner wraps."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from searchrl.world.coarse import ObservationPart, reset_parts
from searchrl.world.config import WorldConfig, check_seed, is_int, need
from searchrl.world.metrics import episode_metrics
from searchrl.world.observe import observation_buffers, observe, observe_worlds
from searchrl.world.reset import DrawnWorld, draw_world, reset_worlds, write_world
from searchrl.world.scenario import PAPER, Scenario
from searchrl.world.state import WorldState, allocate
from searchrl.world.step import StepResult, step
from searchrl.world.streams import WorldStreams


@dataclass
class Transition:
    """What `SearchWorld.step` returns. Observations are those after auto-reset for finished worlds;
    `final_maps`/`final_vector` hold the last observation of the worlds that finished (others are stale). Without
    observations (`observe=False`) the four arrays are None."""

    maps: np.ndarray | None  # (K, N, C, fov, fov) float32, C = 5, or 6 with belief_age_channel
    vector: np.ndarray | None  # (K, N, 3) float32
    result: StepResult
    final_maps: np.ndarray | None  # (K, N, C, fov, fov) float32, valid where result.done
    final_vector: np.ndarray | None  # (K, N, 3) float32, valid where result.done
    metrics: dict[str, np.ndarray]  # (K,) each, episode metrics, valid where result.done
    parts: dict[str, np.ndarray] = field(default_factory=dict)  # key -> (K, *part.shape(N)), after auto-reset
    final_parts: dict[str, np.ndarray] = field(default_factory=dict)  # the same before it, valid where done


class SearchWorld:
    """K independent worlds stepped together.

    With `auto_reset` (training) a finished world is reset on its own, the others untouched; without it (episode
    runners, the PettingZoo env) a finished world keeps stepping and its episode's metrics come with the step that
    ended it. Randomness: one `np.random.Generator` seeded at construction or by `reset(seed)`, or one stream per
    world (`from_maps`). What a reset draws besides the §4.1 sizes and prior (obstacles, where the targets are) is
    the injected `scenario`'s (searchrl/world/scenario.py; the paper's by default). `observe=False` skips the
    observations for controllers that read the state only. `parts` (searchrl/world/coarse.py) are observed beside
    the window and the 3-vector, in `parts` after every reset and step.
    """

    def __init__(
        self,
        config: WorldConfig,
        n_worlds: int,
        seed: int | None = None,
        scenario: Scenario = PAPER,
        auto_reset: bool = True,
        observe: bool = True,
        parts: Sequence[ObservationPart] = (),
    ) -> None:
        need(is_int(n_worlds) and n_worlds >= 1, "n_worlds", n_worlds, "an integer >= 1")
        check_seed(seed)
        scenario.check(config)
        self.config, self.scenario, self.auto_reset, self.observes = config, scenario, auto_reset, observe
        self.state: WorldState = allocate(config, n_worlds)
        self.rng: np.random.Generator | WorldStreams = np.random.default_rng(seed)
        self._obs = observation_buffers(config, n_worlds) if observe else None
        self._final = tuple(np.zeros_like(a) for a in self._obs) if observe else (None, None)
        self.observation: tuple[np.ndarray, np.ndarray] | tuple[None, None] = (None, None)  # of the last reset/step
        # Its own copy of each part: a part may remember the episodes of these worlds (coarse.py)
        self.part_fns = tuple(copy.deepcopy(p) for p in parts) if observe else ()
        self.parts = {p.key: np.zeros((n_worlds, *p.shape(config)), np.float32) for p in self.part_fns}
        self._final_parts = {key: np.zeros_like(a) for key, a in self.parts.items()}
        self._last_map: tuple[int, DrawnWorld] | None = None  # the map seed `_draw_maps` wrote last, and its draw
        self.started = False  # a world is stepped only once reset (`reset`, `from_maps`) has drawn it

    @classmethod
    def from_maps(
        cls,
        config: WorldConfig,
        map_seeds: Sequence[int],
        streams: WorldStreams,
        scenario: Scenario = PAPER,
        observe: bool = True,
    ) -> SearchWorld:
        """Worlds for one episode each: world k reset from `np.random.default_rng(map_seeds[k])` (its map, targets
        and start cells), stepped with draws from its own stream (`streams`, one per world), never reset on its own
        (`start_episodes` starts another episode in a world)."""
        need(len(streams) == len(map_seeds), "streams", len(streams), f"one per map seed ({len(map_seeds)})")
        world = cls(config, len(map_seeds), scenario=scenario, auto_reset=False, observe=observe)
        world.rng = streams
        world._draw_maps(range(len(map_seeds)), map_seeds)
        reset_parts(world.part_fns, world.state, config, np.arange(len(map_seeds)))
        world.observation, world.started = world._observe(), True
        return world

    def start_episodes(self, worlds: Sequence[int], map_seeds: Sequence[int], keys: Sequence[Sequence[int]]) -> None:
        """In a world made by `from_maps`, world worlds[i] starts a new episode: reset from
        `np.random.default_rng(map_seeds[i])`, then stepped with draws from a new stream, `default_rng(keys[i])`;
        the observation of those worlds is made again, the other worlds are untouched. The episode is the one
        `from_maps` would start from that map seed and stream."""
        if not isinstance(self.rng, WorldStreams):
            raise TypeError("start_episodes needs a world made by from_maps (one stream per world), not one generator")
        self.rng.restart(worlds, keys)
        self._draw_maps(worlds, map_seeds)
        if self.observes:
            self.observation = observe_worlds(self.config, self.state, self._obs, np.asarray(worlds, np.int64))
            reset_parts(self.part_fns, self.state, self.config, np.asarray(worlds, np.int64))
            self._observe_parts(np.asarray(worlds, np.int64))

    def _draw_maps(self, worlds: Sequence[int], map_seeds: Sequence[int]) -> None:
        """Reset world worlds[i] from `default_rng(map_seeds[i])`. The map seed written last is written again, not
        drawn again: the repeats of a map come one after another, and a large map's Gaussians cost more than its
        episode's steps. Only that one draw is kept (a map of n = 160 holds 0.4 MB)."""
        for k, seed in zip(worlds, map_seeds, strict=True):
            if self._last_map is None or self._last_map[0] != seed:
                drawn = draw_world(self.config, self.state.n_agents, np.random.default_rng(seed), self.scenario)
                self._last_map = (seed, drawn)
            write_world(self.config, self.state, int(k), self._last_map[1])

    @property
    def n_worlds(self) -> int:
        return self.state.n_worlds

    def _observe(self) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
        self._observe_parts(np.arange(self.n_worlds))
        return observe(self.config, self.state, self._obs) if self.observes else (None, None)

    def _observe_parts(self, worlds: np.ndarray) -> None:
        for part in self.part_fns:
            part.fill(self.state, self.config, self.parts[part.key], worlds)

    def reset(self, seed: int | None = None, mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Reset the worlds in `mask` (all by default); `seed` reseeds the generator first."""
        if seed is not None:
            check_seed(seed)
            self.rng = np.random.default_rng(seed)
        mask = np.ones(self.n_worlds, bool) if mask is None else np.asarray(mask, bool)
        reset_worlds(self.config, self.state, mask, self.rng, self.scenario)
        reset_parts(self.part_fns, self.state, self.config, np.flatnonzero(mask))
        self.observation, self.started = self._observe(), True
        return self.observation

    def step(self, actions: np.ndarray) -> Transition:
        """Step all worlds with actions (K, N), then (with auto_reset) reset the finished ones."""
        if not self.started:  # the state is empty memory: its kernels would read garbage
            raise RuntimeError("step() called before reset(): reset the worlds first")
        result = step(self.config, self.state, actions, self.rng)
        maps, vector = self._observe()
        done = result.done
        metrics: dict[str, np.ndarray] = {}
        if done.any():
            metrics = episode_metrics(self.state)
            if self.auto_reset:
                if self.observes:
                    self._final[0][done] = maps[done]
                    self._final[1][done] = vector[done]
                    for key, values in self.parts.items():
                        self._final_parts[key][done] = values[done]
                reset_worlds(self.config, self.state, done, self.rng, self.scenario)
                if self.observes:  # only the reset worlds changed since the step's observation
                    maps, vector = observe_worlds(self.config, self.state, self._obs, np.flatnonzero(done))
                    reset_parts(self.part_fns, self.state, self.config, np.flatnonzero(done))
                    self._observe_parts(np.flatnonzero(done))
        self.observation = (maps, vector)
        final = self._final if self.auto_reset else (maps, vector)
        final_parts = self._final_parts if self.auto_reset else self.parts
        return Transition(maps, vector, result, final[0], final[1], metrics, self.parts, final_parts)
