"""The one episode runner: a controller plays episodes in batched worlds through `SearchWorld.step`, each world
starting the next waiting episode when its own ends.

Evaluation (a grid cell's maps, searchrl/evaluate/runner.py), validation during training
(searchrl/train/callbacks.py), `python -m searchrl.render` and the evaluation bench all play their episodes here,
so a policy's validation number and its evaluation number come from the same code: the same worlds, the same
draws, the same inference path (`PolicyController`, searchrl/controllers/policy.py).

An episode is named by its map seed (its map, targets and start cells: `np.random.default_rng(map_seed)`) and its
key, a tuple of ints >= 0 from which its own two random streams are seeded: (*key, 0) for the world's step draws,
(*key, 1) for the controller's. Nothing an episode draws depends on the world that plays it or on the episodes
batched beside it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from searchrl.controllers.base import Controller
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.scenario import PAPER, Scenario
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams
from searchrl.world.truth import prior_qualities

ControllerFactory = Callable[[WorldConfig, WorldStreams], Controller]


def episode_streams(keys: Sequence[Sequence[int]]) -> tuple[WorldStreams, WorldStreams]:
    """(the worlds', the controller's) streams of the episodes with these keys: (*key, 0) and (*key, 1)."""
    return WorldStreams([(*key, 0) for key in keys]), WorldStreams([(*key, 1) for key in keys])


class EpisodeQueue:
    """The episodes of a batch in order, each a (map seed, key) pair: the first K start in the K worlds, and each
    world whose episode ends starts the next one waiting (`start`). `playing` (K,) int64 holds the episode (an
    index into the pairs) each world plays, `quality` (episodes,) the prior quality of each episode begun."""

    def __init__(
        self, map_seeds: Sequence[int], keys: Sequence[Sequence[int]], n_worlds: int, controller_streams: WorldStreams
    ) -> None:
        self.map_seeds, self.keys, self.controller_streams = list(map_seeds), list(keys), controller_streams
        self.playing = np.arange(n_worlds)
        self.quality = np.full(len(self.map_seeds), np.nan)
        self.waiting = n_worlds  # the next episode to start

    def __len__(self) -> int:
        return len(self.map_seeds)

    def start(self, world: SearchWorld, ended: np.ndarray) -> np.ndarray:
        """Start the next waiting episodes in worlds of `ended` (K,) bool, in index order, while any wait; returns
        (K,) bool, the worlds that started one."""
        started = np.zeros(len(ended), bool)
        worlds = np.flatnonzero(ended)[: len(self) - self.waiting]
        if not len(worlds):
            return started
        episodes = np.arange(self.waiting, self.waiting + len(worlds))
        self.waiting += len(worlds)
        keys = [self.keys[e] for e in episodes]
        world.start_episodes(worlds, [self.map_seeds[e] for e in episodes], [(*key, 0) for key in keys])
        self.controller_streams.restart(worlds, [(*key, 1) for key in keys])
        self.playing[worlds] = episodes
        self.quality[episodes] = prior_qualities(world.state, worlds)
        started[worlds] = True
        return started


def play(
    world: SearchWorld,
    controller: Controller,
    on_step: Callable[[SearchWorld, np.ndarray], None] | None = None,
    on_done: Callable[[WorldState, np.ndarray, np.ndarray], None] | None = None,
    queue: EpisodeQueue | None = None,
) -> dict[str, np.ndarray]:
    """Step `world` (made without auto-reset) with `controller` from its current observation until every world
    has finished an episode, and with `queue` until the queue's episodes have all ended too, a world starting the
    next waiting one (`EpisodeQueue.start`, then `controller.reset` of that world) as soon as its own ends. Returns
    each episode's metrics, (episodes,) per name (searchrl/world/metrics.py): world k's without a queue.

    A world whose episode ended and that has none to start keeps stepping with the batch (its later steps count
    for nothing); the controller acts only for the running ones (`active`). `on_step(world, counted)` sees the
    state after each step, `counted` (K,) bool the worlds whose episode that step belonged to;
    `on_done(state, first, playing)` the state as the worlds in `first` end their episodes, `playing` (K,) the
    episode each world plays.
    """
    k = world.n_worlds
    playing = np.arange(k) if queue is None else queue.playing
    episodes = k if queue is None else len(queue)
    controller.reset(world.state, np.ones(k, bool))
    maps, vector = world.observation
    running = np.ones(k, bool)
    final: dict[str, np.ndarray] = {}
    while running.any():
        transition = world.step(controller.act(world.state, maps, vector, active=running))
        maps, vector = transition.maps, transition.vector
        counted = running.copy()
        first = transition.result.done & counted
        if first.any():
            for name, values in transition.metrics.items():
                final.setdefault(name, np.zeros(episodes, values.dtype))[playing[first]] = values[first]
            running &= ~first
            if on_done:
                on_done(world.state, first, playing)
        if on_step:
            on_step(world, counted)
        if first.any() and queue is not None:
            started = queue.start(world, first)
            if started.any():
                controller.reset(world.state, started)
                running |= started
                maps, vector = world.observation
    return final


def play_episodes(
    controller_factory: ControllerFactory,
    config: WorldConfig,
    map_seeds: Sequence[int],
    keys: Sequence[Sequence[int]],
    scenario: Scenario = PAPER,
    needs_observation: bool = True,
    on_step: Callable[[SearchWorld, np.ndarray], None] | None = None,
    on_done: Callable[[WorldState, np.ndarray, np.ndarray], None] | None = None,
    slots: int | None = None,
) -> dict[str, np.ndarray]:
    """One episode per (map seed, key) in worlds of `config` under `scenario`, played by
    `controller_factory(config, controller streams)`; their metrics, (episodes,) per name, and `prior_quality`,
    how well the prior the agents start from points at the episode's targets (searchrl/world/truth.py).

    `slots` worlds step together (every episode at once by default): each starts the next waiting episode when
    its own ends (`EpisodeQueue`), so no world idles while episodes wait. An episode draws from its own map seed
    and streams whichever world plays it and beside whichever others, so `slots` changes the speed, not a bit of
    the episodes."""
    if len(keys) != len(map_seeds):
        raise ValueError(f"{len(keys)} keys for {len(map_seeds)} map seeds: one key per episode")
    k = len(map_seeds) if slots is None else max(1, min(int(slots), len(map_seeds)))
    world_streams, controller_streams = episode_streams(keys[:k])
    world = SearchWorld.from_maps(config, map_seeds[:k], world_streams, scenario, observe=needs_observation)
    queue = EpisodeQueue(map_seeds, keys, k, controller_streams)
    queue.quality[:k] = prior_qualities(world.state)
    final = play(world, controller_factory(config, controller_streams), on_step, on_done, queue)
    return {**final, "prior_quality": queue.quality}
