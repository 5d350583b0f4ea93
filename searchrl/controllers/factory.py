"""The one controller factory: evaluation, validation during training, render and the evaluation bench all make
the controllers their episodes are played with (searchrl/controllers/episodes.py) here, so a heuristic is built
from the registry the same way everywhere and a trained policy acts through the same `PolicyController`.

A factory is `factory(config, seed) -> Controller`: `config` a cell's world settings, `seed` an int or the
episodes' `WorldStreams` (one random stream per world). A policy with more inputs than the window and the 3-vector
needs no other controller: its network names the observation parts it reads (searchrl/policies/networks.py), and
`PolicyController` observes them.
"""

from __future__ import annotations

from typing import Any

from searchrl.controllers.base import Controller
from searchrl.controllers.episodes import ControllerFactory
from searchrl.controllers.policy import PolicyController
from searchrl.controllers.registry import make_controller
from searchrl.policies.actor import Actor
from searchrl.world.config import WorldConfig
from searchrl.world.streams import WorldStreams


def heuristic_factory(
    name: str, settings: dict[str, Any] | None = None, check: WorldConfig | None = None
) -> ControllerFactory:
    """The registered heuristic `name` with `settings` (plain values without `name`). With `check`, one is built in
    that world first, so an unknown name or a refused setting is a ConfigError before any work."""
    settings = dict(settings or {})

    def factory(config: WorldConfig, seed: int | WorldStreams = 0) -> Controller:
        return make_controller(name, config, seed=seed, settings=settings)

    if check is not None:
        factory(check)
    return factory


def policy_factory(actor: Actor, deterministic: bool = False) -> ControllerFactory:
    """A trained policy's actor (loaded once, it serves every cell) acting through `PolicyController`."""

    def factory(config: WorldConfig, seed: int | WorldStreams = 0) -> Controller:
        return PolicyController(actor, config, deterministic=deterministic, seed=seed)

    return factory
