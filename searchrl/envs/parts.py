"""Observation parts by name: what an env observes beside the paper's window and 3-vector.

A part is an object of searchrl/world/coarse.py's `ObservationPart` protocol; it registers its class here under its
`key` (`register_part`, as a decorator or one call), and a network or critic asks for it by that name
(searchrl/policies/networks.py). The env then holds it in every observation as `obs[key]`, `shape(config)[1:]`
per slot.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable
from difflib import get_close_matches
from typing import Any

from searchrl.world.coarse import ObservationPart, OwnMap, TrueState

PARTS: dict[str, Callable[..., ObservationPart]] = {}


def register_part(cls: Callable[..., ObservationPart]) -> Callable[..., ObservationPart]:
    """Register a part class under its `key` (usable as a decorator); ValueError if the name is taken by another."""
    key = cls.key
    if PARTS.get(key, cls) is not cls:
        raise ValueError(f"observation part {key!r} is registered already ({PARTS[key]!r})")
    PARTS[key] = cls
    return cls


register_part(OwnMap)
register_part(TrueState)


def make_part(name: str, **settings: Any) -> ObservationPart:
    """The part registered as `name`, built with those of `settings` its class takes (a coarse part takes `grid`,
    a part of one vector per agent none); ValueError naming the nearest registered name."""
    if name not in PARTS:
        near = get_close_matches(name, PARTS, n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise ValueError(f"observation part {name!r} is not registered{hint}: one of {sorted(PARTS)}")
    takes = inspect.signature(PARTS[name]).parameters
    return PARTS[name](**{key: value for key, value in settings.items() if key in takes})


def make_parts(requests: Iterable[tuple[str, dict[str, Any]]]) -> tuple[ObservationPart, ...]:
    """One part per distinct name of (name, settings) requests, in order of first request."""
    seen: dict[str, ObservationPart] = {}
    for name, settings in requests:
        if name not in seen:
            seen[name] = make_part(name, **settings)
    return tuple(seen.values())
