"""The one episode runner: a controller plays batched worlds, one episode each, through `SearchWorld.step`.

Evaluation (a grid cell's maps, searchrl/evaluate/runner.py), validation during training
(searchrl/train/validation.py), `python -m searchrl.render` and the evaluation bench all play their episodes here,
so a policy's validation number and its evaluation number come from the same code: the same worlds, the same
draws, the same inference path (`PolicyController`, searchrl/controllers/policy.py).

An episode is named by its map seed (its map, targets and start cells: `np.random.default_rng(map_seed)`) and its
key, a tuple of ints >= 0 from which its own two random streams are seeded: (*key, 0) for the world's step draws,
(*key, 1) for the controller's. Nothing an episode draws depends on the episodes batched beside it.
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


def play(
    world: SearchWorld,
    controller: Controller,
    on_step: Callable[[SearchWorld, np.ndarray], None] | None = None,
    on_done: Callable[[WorldState, np.ndarray], None] | None = None,
) -> dict[str, np.ndarray]:
    """Step `world` (made without auto-reset) with `controller` from its current observation until every world
    has finished an episode; returns each world's episode metrics, (K,) per name (searchrl/world/metrics.py).

    A finished world keeps stepping with the batch (its later steps count for nothing) and the controller acts only
    for the running ones (`active`). `on_step(world, counted)` sees the state after each step, `counted` (K,) bool
    the worlds whose episode that step belonged to; `on_done(state, first)` the state as the worlds in `first` end.
    """
    k = world.n_worlds
    controller.reset(world.state, np.ones(k, bool))
    maps, vector = world.observation
    finished = np.zeros(k, bool)
    final: dict[str, np.ndarray] = {}
    while not finished.all():
        transition = world.step(controller.act(world.state, maps, vector, active=~finished))
        maps, vector = transition.maps, transition.vector
        counted = ~finished
        first = transition.result.done & counted
        if first.any():
            for name, values in transition.metrics.items():
                final.setdefault(name, np.zeros(k, values.dtype))[first] = values[first]
            finished |= first
            if on_done:
                on_done(world.state, first)
        if on_step:
            on_step(world, counted)
    return final


def play_episodes(
    controller_factory: ControllerFactory,
    config: WorldConfig,
    map_seeds: Sequence[int],
    keys: Sequence[Sequence[int]],
    scenario: Scenario = PAPER,
    needs_observation: bool = True,
    on_step: Callable[[SearchWorld, np.ndarray], None] | None = None,
    on_done: Callable[[WorldState, np.ndarray], None] | None = None,
) -> dict[str, np.ndarray]:
    """One episode per (map seed, key), all in one batch of worlds of `config` under `scenario`, played by
    `controller_factory(config, controller streams)`; their metrics, (episodes,) per name, and `prior_quality`,
    how well the prior the agents start from points at the episode's targets (searchrl/world/truth.py)."""
    world_streams, controller_streams = episode_streams(keys)
    world = SearchWorld.from_maps(config, map_seeds, world_streams, scenario, observe=needs_observation)
    quality = prior_qualities(world.state)
    return {**play(world, controller_factory(config, controller_streams), on_step, on_done), "prior_quality": quality}
