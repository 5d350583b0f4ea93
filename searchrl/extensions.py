"""`extensions=[module, ...]`: a user's modules, imported before a config is checked, that register their own parts.

What rl-baselines3-zoo's `--gym-packages` does for environments, for every kind of part searchrl names: a module of
a user's package (or a research script in `analysis/`) registers networks and critics
(searchrl/policies/networks.py), observation parts (searchrl/envs/parts.py) and heuristics or teachers
(searchrl/controllers/registry.py) where it defines them, and a command line uses them by name:

    python -m searchrl.train +model=b extensions=[my_pkg.parts] network.extractor=my_cnn

The entry points import the modules named on the command line before Hydra composes (a heuristic's settings become
a config group option), and every app imports those of its config again, so the jobs a launcher starts in other
processes (joblib, SLURM) register the same parts. A run records its extensions in config.yaml; evaluating its
checkpoint needs them on the command line again: nothing a folder holds is imported on its own word.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable

from searchrl.multirun import refuse
from searchrl.world.config import ConfigError


def from_command_line(argv: Iterable[str]) -> list[str]:
    """The modules an `extensions=` (or `+extensions=`) argument names: `extensions=[a.b,c]` or `extensions=a.b`."""
    modules: list[str] = []
    for arg in argv:
        key, _, value = arg.lstrip("+~").partition("=")
        if key == "extensions" and value not in ("", "[]", "null"):
            inner = value[1:-1] if value.startswith("[") and value.endswith("]") else value
            modules += [m.strip().strip("'\"") for m in inner.split(",") if m.strip()]
    return modules


def import_modules(modules: Iterable[str]) -> None:
    """Import each module (once; Python keeps them); ConfigError in one line naming one that cannot be imported."""
    for name in modules:
        try:
            importlib.import_module(str(name))
        except Exception as err:  # ModuleNotFoundError, or the module's own error while registering
            detail = str(err).splitlines()[0] if str(err) else ""
            raise ConfigError(
                f"extensions: {name!r} cannot be imported ({type(err).__name__}: {detail}); give "
                "importable module names, e.g. extensions=[my_package.parts]"
            ) from None


def import_from_command_line(argv: Iterable[str]) -> None:
    """`import_modules` of the command line's `extensions=`; a module that cannot be imported is refused in one line
    (`searchrl.multirun.refuse`), before Hydra runs."""
    try:
        import_modules(from_command_line(argv))
    except ConfigError as err:
        refuse(str(err))
