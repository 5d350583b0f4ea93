"""Observation parts by name: what an env observes beside the paper's window and 3-vector.

A part is an object of searchrl/world/coarse.py's `ObservationPart` protocol; it registers its class here under its
`key` (`register_part`, as a decorator or one call), and a network or critic asks for it by that name
(searchrl/policies/networks.py). The env then holds it in every observation as `obs[key]`, `shape(config)[1:]`
per slot.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable
from typing import Any

from searchrl.registry import Registry
from searchrl.world.coarse import ObservationPart, OwnMap, TrueState
from searchrl.world.config import ConfigError

PARTS: Registry[Callable[..., ObservationPart]] = Registry("observation part", (OwnMap, TrueState), key="key")


def register_part(cls: Callable[..., ObservationPart]) -> Callable[..., ObservationPart]:
    """Register a part class under its `key` (usable as a decorator); ConfigError if another holds the name."""
    return PARTS.register(part=cls)


def make_part(name: str, /, **settings: Any) -> ObservationPart:
    """The part registered as `name`, built with those of `settings` its class takes (a coarse part takes `grid`,
    a part of one vector per agent none); ConfigError naming the nearest registered name."""
    return PARTS.lookup(name)(**taken_settings(name, settings))


def taken_settings(name: str, settings: dict[str, Any]) -> dict[str, Any]:
    """Those of `settings` part `name`'s class takes."""
    takes = inspect.signature(PARTS.lookup(name)).parameters
    return {key: value for key, value in settings.items() if key in takes}


def make_parts(requests: Iterable[tuple[str, dict[str, Any]]]) -> tuple[ObservationPart, ...]:
    """One part per distinct name of (name, settings) requests, in order of first request. The env holds one
    observation per key, so a part asked for twice with other settings is refused in one line rather than built
    once with the first (an actor's and a critic's requests are kept apart: searchrl/policies/networks.py)."""
    seen: dict[str, tuple[dict[str, Any], ObservationPart]] = {}
    for name, settings in requests:
        taken = taken_settings(name, settings)
        if name in seen and seen[name][0] != taken:
            raise ConfigError(
                f"observation part {name!r} is asked for with {seen[name][0]} and with {taken}: the env holds one "
                f"{name!r}, so give both the same settings"
            )
        if name not in seen:
            seen[name] = (taken, make_part(name, **taken))
    return tuple(part for _, part in seen.values())
