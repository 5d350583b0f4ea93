"""`python -m searchrl.parts [extensions=[my_pkg.parts]]`: every part a command line can choose, with its settings.

One block per registry (searchrl/registry.py): the setting that chooses a part, then each name, the class that makes
it and the settings it takes with their defaults (a heuristic's dataclass, or its class's typed keyword arguments).
`extensions=` imports a user's modules first, as the apps do, so their parts are listed beside the shipped ones.
"""

from __future__ import annotations

import sys
from dataclasses import MISSING, fields
from typing import Any

from searchrl.command_line import from_command_line, import_modules
from searchrl.registry import settings_of
from searchrl.world.config import ConfigError


def registries() -> list:
    """Every registry, in the order of a recipe: the network, its critic and parts, the reward, the heuristics,
    the scenario's parts."""
    from searchrl.controllers.registry import HEURISTICS
    from searchrl.envs.parts import PARTS
    from searchrl.envs.rewards import REWARDS
    from searchrl.policies.networks import CRITICS, NETWORKS
    from searchrl.world.scenario import PARTS as SCENARIO_PARTS

    return [NETWORKS, CRITICS, PARTS, REWARDS, HEURISTICS, *SCENARIO_PARTS.values()]


def settings(part: Any) -> dict[str, Any]:
    """The settings `part` takes and their defaults: a heuristic's dataclass, or the registry's settings dataclass
    of its class (searchrl/registry.py `settings_of`); a part with an untyped argument says so."""
    if hasattr(part, "schema") and hasattr(part, "settings"):  # a heuristic's entry: its dataclass
        return part.settings()
    try:
        schema = settings_of(part)
    except ConfigError as err:
        return {"cannot be configured": str(err)}
    return {f.name: f.default_factory() if f.default_factory is not MISSING else f.default for f in fields(schema)}


def describe(part: Any) -> str:
    """`module.Class`, and its settings as `name=default`."""
    made_by = getattr(part, "cls", part)
    name = "none (the policy's shared trunk)" if made_by is None else f"{made_by.__module__}.{made_by.__qualname__}"
    values = ", ".join(f"{k}={v!r}" for k, v in settings(part).items())
    return f"{name}" + (f"; settings: {values}" if values else "")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if any(arg in ("-h", "--help") for arg in argv):
        print(__doc__.strip())
        return 0
    unknown = [arg for arg in argv if not arg.lstrip("+").startswith("extensions=")]
    try:
        if unknown:
            raise ConfigError(f"{unknown[0]} is not allowed: python -m searchrl.parts takes extensions=[...] only")
        import_modules(from_command_line(argv))
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    for registry in registries():
        print(f"{registry.setting}:")
        for name, part in registry.items():
            print(f"  {name}: {describe(part)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
