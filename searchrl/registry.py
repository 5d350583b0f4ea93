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

Every refusal is a `ConfigError` (a `ValueError`), which the entry points print as one line. A registry is a plain
dict besides, so reading it (`name in NETWORKS`, `NETWORKS.items()`) and a test's `mock.patch.dict` work as on any.
"""

from __future__ import annotations

from collections.abc import Iterable
from difflib import get_close_matches
from typing import Any, TypeVar

from searchrl.world.config import ConfigError

T = TypeVar("T")
_DECORATE = object()  # `register(name)` without a part: a decorator (a part may be None: the shared critic)


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

    def lookup(self, name: object, setting: str | None = None) -> T:
        """The part registered as `name`; ConfigError naming `setting` (default the registry's), the value, every
        registered name and the nearest one."""
        if isinstance(name, str) and name in self:
            return self[name]
        near = get_close_matches(name, list(self), n=1) if isinstance(name, str) else []
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise ConfigError(f"{setting or self.setting}={name!r} is not allowed: one of {', '.join(self)}{hint}")
