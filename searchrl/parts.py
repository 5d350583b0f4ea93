"""`python -m searchrl.parts [extensions=[my_pkg.parts]]`: every part a command line can choose, with its settings.

One block per registry (searchrl/registry.py): the setting that chooses a part, then each name, the class that makes
it and the settings it takes with their defaults (a dataclass's fields, or its class's keyword arguments).
`extensions=` imports a user's modules first, as the apps do, so their parts are listed beside the shipped ones.
"""

from __future__ import annotations

import inspect
import sys
from dataclasses import MISSING, fields, is_dataclass
from typing import Any

from searchrl.command_line import from_command_line, import_modules
from searchrl.world.config import ConfigError

# Arguments a part gets from the app, not from its settings
_GIVEN = {"self", "config", "seed", "rules", "observation_space", "features_dim", "args", "kwargs"}


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
    """The settings `part` takes and their defaults ("required" where it has none: a part's own arguments)."""
    if hasattr(part, "schema") and hasattr(part, "settings"):  # a heuristic's entry: its dataclass
        return part.settings()
    if is_dataclass(part):
        factory = {f.name: f.default_factory for f in fields(part) if f.default_factory is not MISSING}
        return {f.name: factory[f.name]() if f.name in factory else f.default for f in fields(part)}
    if not callable(part):
        return {}
    parameters = inspect.signature(part).parameters.values()
    return {
        p.name: "required" if p.default is inspect.Parameter.empty else p.default
        for p in parameters
        if p.name not in _GIVEN and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    }


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
