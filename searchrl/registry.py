"""One registry type for every kind of part a command line chooses by name.

Networks and critics (`network.extractor=`, `critic.name=`), observation parts, rewards (`reward=`), heuristics
(`controller=`, `imitation.teacher=`) and the scenario's obstacle laws, target placers and prior families
(`scenario.<part>.kind=`) are each a `Registry`: a dict from a name to what makes the part, with one way in and one
way to ask for a name. Its rules, the same for every kind (tests/test_registry_rules.py):

- `register` adds a name, as a decorator (`@NETWORKS.register("swept_cnn")`) or a call; a name taken from the class
  itself (`key`, `kind`) where the kind names its parts so. The same part registered again under its name is
  accepted (a module imported twice, an extension named on two command lines); another part under a taken name is
  refused in one line naming the setting and the names taken.
- `lookup` gives the part of a name or refuses in one line: the setting, the value, every registered name and the
  nearest one (`controller='planer' is not allowed: one of surfing, …, rollout (did you mean 'rollout'?)`).

- `settings_of` gives a part's settings dataclass: the typed keyword arguments of its constructor with their defaults
  (`def __init__(self, weight: float = 1.0)` is the setting `weight`), less those the app gives it; `schema`
  extends a config node's dataclass by them, which Hydra then types (a setting the part does not take, or a value
  of another type, refused before any work).

Every refusal is a `ConfigError` (a `ValueError`), which the entry points print as one line. A registry is a plain
dict besides, so reading it (`name in NETWORKS`, `NETWORKS.items()`) and a test's `mock.patch.dict` work as on any.
"""

from __future__ import annotations

import dataclasses
import inspect
import types
import typing
from collections.abc import Iterable
from difflib import get_close_matches
from typing import Any, TypeVar, get_type_hints

import numpy as np

from searchrl.world.config import ConfigError, is_int

T = TypeVar("T")
_DECORATE = object()  # `register(name)` without a part: a decorator (a part may be None: the shared critic)
# Constructor arguments the app gives a part, never a setting: the world, its seed, the rules a planner plays, the
# observation space and widths of a network (its recipe's `network.*`), a part's grid (`network.grid`)
GIVEN = frozenset(
    {
        "self",
        "config",
        "seed",
        "rules",
        "observation_space",
        "features_dim",
        "conv_channels",
        "vector_size",
        "fc_sizes",
        "grid",
    }
)


class Registry(dict[str, T]):
    """Parts of one kind by name. `setting` is what a command line sets to choose one (`network.extractor`);
    `key`, where given, is the class attribute that names a part registered without a name (`kind`)."""

    def __init__(self, setting: str, parts: dict[str, T] | Iterable[T] = (), key: str | None = None) -> None:
        """`parts`: the built-in ones, by name, or classes registered under their `key`."""
        super().__init__()
        self.setting, self.key = setting, key
        for name, part in parts.items() if isinstance(parts, dict) else ((None, part) for part in parts):
            self.register(name, part)

    def register(self, name: str | None = None, part: Any = _DECORATE) -> Any:
        """Add `part` under `name` (by default its `key` attribute) and return it; without `part`, a decorator that
        does so. ConfigError for a name that is not a non-empty string or that another part holds."""
        if part is _DECORATE:
            return lambda cls: self.register(name, cls)
        name = getattr(part, self.key, None) if name is None and self.key else name
        if not isinstance(name, str) or not name:
            raise ConfigError(f"{self.setting}={name!r} cannot be registered: a name is a non-empty string")
        if name in self and self[name] != part:
            raise ConfigError(
                f"{self.setting}={name!r} cannot be registered: a new name is needed, not one of {', '.join(self)}"
            )
        self[name] = part
        return part

    def lookup(self, name: object, setting: str | None = None, other: str = "") -> T:
        """The part registered as `name`; ConfigError naming `setting` (default the registry's), the value, every
        registered name (and `other`, what the setting's command takes instead) and the nearest one."""
        if isinstance(name, str) and name in self:
            return self[name]
        near = get_close_matches(name, list(self), n=1) if isinstance(name, str) else []
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        names = ", ".join(self) + (f", or {other}" if other else "")
        raise ConfigError(f"{setting or self.setting}={name!r} is not allowed: one of {names}{hint}")

    def schema(self, name: str, base: type, key: str, sources: Iterable[Any] = ()) -> type:
        """`base` (the dataclass of the part's config node) extended by the settings of part `name` and of
        `sources` (the observation parts a network reads), with `key` defaulting to `name`: what Hydra types the
        node with once the part is chosen. Made once per part and named after its module but not kept there, so a
        launcher (joblib's loky, submitit: cloudpickle) sends the class itself with a job's config: a job process
        that has not yet imported the part's module could not find it there."""
        part = self.lookup(name)
        cache = self.__dict__.setdefault("_schemas", {})
        if (name, base, part) in cache:  # keyed by the part too: a module imported again registers a new class
            return cache[(name, base, part)]
        taken = {f.name for f in dataclasses.fields(base)}
        specs: dict[str, tuple[str, Any, Any]] = {}
        for source in [part, *sources] if part is not None else []:
            for f in dataclasses.fields(settings_of(source, f"{self.setting}={name}")):
                if f.name not in taken:
                    value = dataclasses.field(default=f.default, default_factory=f.default_factory)
                    specs[f.name] = (f.name, f.type, value)
        specs[key] = (key, str, dataclasses.field(default=name))
        module = getattr(part, "__module__", base.__module__) if part is not None else base.__module__
        label = "".join(c if c.isalnum() else "_" for c in f"{base.__name__}_{name}")
        schema = dataclasses.make_dataclass(f"_{label}", list(specs.values()), bases=(base,))
        schema.__module__ = module
        cache[(name, base, part)] = schema
        return schema


def settings_of(part: Any, label: str = "part") -> type:
    """A dataclass of the settings `part` takes: its constructor's keyword arguments with a default and a type, less
    those the app gives (GIVEN); a dataclass part is its own. ConfigError for a setting without a type."""
    if dataclasses.is_dataclass(part) and isinstance(part, type):
        return part
    if part is None or not callable(part):
        return dataclasses.make_dataclass("NoSettings", [])
    hints = get_type_hints(part.__init__) if isinstance(part, type) else get_type_hints(part)
    specs = []
    for p in inspect.signature(part).parameters.values():
        if p.name in GIVEN or p.kind not in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY):
            continue
        if p.default is inspect.Parameter.empty or p.name not in hints:
            raise ConfigError(f"{label}: its argument {p.name!r} needs a type and a default to be a setting")
        default = p.default
        value = dataclasses.field(default_factory=lambda d=default: list(d)) if isinstance(default, list) else default
        specs.append(
            (
                p.name,
                hints[p.name],
                dataclasses.field(default=value) if not isinstance(value, dataclasses.Field) else value,
            )
        )
    return dataclasses.make_dataclass(f"{getattr(part, '__name__', 'Part')}Settings", specs, frozen=True)


def typed_settings(schema: type, values: dict[str, Any], where: str) -> dict[str, Any]:
    """`values` (settings of the dataclass `schema`, each a field of it) checked against their fields' types, as
    Hydra checks a node: an int given for a float becomes that float; ConfigError "where.key=value is not allowed:
    a <type>" for a value of another type. The path of settings that come as a mapping (a teacher's arguments, a
    planner's base rule, a bench's JSON) rather than through a typed config node."""
    hints = get_type_hints(schema)
    checked = {}
    for key, value in values.items():
        ok, checked[key] = _fits(value, hints.get(key, Any))
        if not ok:
            raise ConfigError(f"{where}.{key}={value!r} is not allowed: a value of type {_name(hints[key])}")
    return checked


def _fits(value: Any, hint: Any) -> tuple[bool, Any]:
    """(whether `value` is of the type `hint`, the value as that type: an int as a float where a float is asked)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Any:
        return True, value
    if origin in (typing.Union, types.UnionType):
        for arm in args:
            ok, as_arm = _fits(value, arm)
            if ok:
                return True, as_arm
        return False, value
    if hint is type(None):
        return value is None, value
    if hint is float:
        number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
        return number, float(value) if number else value
    if hint is int:
        return is_int(value), int(value) if is_int(value) else value
    if hint is bool:
        return isinstance(value, (bool, np.bool_)), bool(value) if isinstance(value, (bool, np.bool_)) else value
    if origin is typing.Literal:
        return value in args, value
    if origin in (list, tuple) and isinstance(value, (list, tuple)):
        fixed = origin is tuple and args and args[-1] is not Ellipsis  # tuple[int, str]: one type per position
        if fixed and len(value) != len(args):
            return False, value
        items = [_fits(item, args[i] if fixed else (args[0] if args else Any)) for i, item in enumerate(value)]
        return all(ok for ok, _ in items), origin(item for _, item in items)
    if origin is dict:
        if not isinstance(value, dict):
            return False, value
        key, item = args if args else (Any, Any)
        pairs = [(_fits(k, key), _fits(v, item)) for k, v in value.items()]
        return all(k[0] and v[0] for k, v in pairs), {k[1]: v[1] for k, v in pairs}
    return isinstance(value, origin or hint), value


def _name(hint: Any) -> str:
    return str(hint).replace("typing.", "") if typing.get_args(hint) else getattr(hint, "__name__", str(hint))
