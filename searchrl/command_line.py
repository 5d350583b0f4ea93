"""What the entry points check on a command line before Hydra runs it, each refused in one line naming the value
(`multirun.refuse`, exit status 2) where Hydra's own message is a traceback or a page of search paths.

- **`extensions=[module, ...]`**: a user's modules, imported before a config is checked, that register their own
  parts. What rl-baselines3-zoo's `--gym-packages` does for environments, for every kind of part searchrl names: a
  module of a user's package (or a research script in `analysis/`) registers networks and critics
  (searchrl/policies/networks.py), observation parts (searchrl/envs/parts.py) and heuristics or teachers
  (searchrl/controllers/registry.py) where it defines them, and a command line uses them by name:

      python -m searchrl.train +model=b extensions=[my_pkg.parts] network.extractor=my_cnn

  The entry points import the modules named on the command line before Hydra composes (a heuristic's settings
  become a config group option), and every app imports those of its config again (`import_modules`), so the jobs a
  launcher starts in other processes (joblib, SLURM) register the same parts. A run records its extensions in
  config.yaml; evaluating its checkpoint needs them on the command line again: nothing a folder holds is imported
  on its own word.
- **`resume=`** names a folder, and every **`[+]group=option`** an option that exists (with the nearest one).
- **Every job composes.** Hydra composes a run's config from its command line when the run starts, and a
  multirun's jobs one at a time as the launcher reaches them. A value its setting cannot take (`grid.repeats=1.5`,
  `controller.w_p=abc`, one value of a sweep's list) is then five lines of Hydra's, and in a multirun it ends the
  sweep at that job: the valid jobs after it never run. `check_jobs_compose` composes the command line with Hydra's
  own compose API first, each value of each swept setting in turn.
"""

from __future__ import annotations

import importlib
import os
import re
from collections.abc import Iterable
from pathlib import Path

from searchrl.multirun import refuse
from searchrl.shared_schema import nearest
from searchrl.world.config import ConfigError

# Hydra's flags that take no value; any other flag (`--cfg job`, `--config-name x`, `--info`) leaves the check to Hydra
_PLAIN_FLAGS = {"-m", "--multirun"}


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
        except (Exception, SystemExit) as err:  # ModuleNotFoundError, the module's own error, or its sys.exit()
            detail = str(err).splitlines()[0] if str(err) else ""
            if isinstance(err, SystemExit):
                detail = f"it calls sys.exit({err.code!r}) when imported"
            raise ConfigError(
                f"extensions: {name!r} cannot be imported ({type(err).__name__}: {detail}); give "
                "importable module names, e.g. extensions=[my_package.parts]"
            ) from None


def from_recipes(argv: Iterable[str]) -> list[str]:
    """The modules the recipes a command line chooses (`+experiment=<name>`) name in their `extensions:`, and those
    of the recipes they build on (their defaults' `/experiment/...`): a recipe's reward or network is then an
    option of its group when Hydra composes it."""
    import yaml

    from searchrl.shared_schema import CONF_DIR

    modules: list[str] = []
    recipes = [arg.lstrip("+").partition("=")[2] for arg in argv if arg.lstrip("+").startswith("experiment=")]
    seen: set[str] = set()
    while recipes:
        name = recipes.pop().strip("'\"")
        path = CONF_DIR / "experiment" / f"{name}.yaml"
        if name in seen or "," in name or not path.is_file():
            continue  # a sweep over recipes, or a name check_group_choices refuses
        seen.add(name)
        loaded = yaml.safe_load(path.read_text()) or {}
        modules += [str(m) for m in loaded.get("extensions") or []]
        for entry in loaded.get("defaults") or []:
            if isinstance(entry, str) and entry.startswith("/experiment/"):
                recipes.append(entry.removeprefix("/experiment/"))
    return modules


def import_from_command_line(argv: Iterable[str]) -> None:
    """`import_modules` of the command line's `extensions=` and its recipes' (`from_recipes`); a module that cannot
    be imported is refused in one line (`searchrl.multirun.refuse`), before Hydra runs."""
    argv = list(argv)
    try:
        import_modules(from_command_line(argv) + from_recipes(argv))
    except ConfigError as err:
        refuse(str(err))


def _unquoted(value: str) -> str:
    if len(value) >= 2 and value[0] == value[-1] and value[0] in "'\"":  # quoted for Hydra: a path with spaces
        return value[1:-1]
    return value


def check_resume_argument(argv: list[str]) -> None:
    """Hydra makes `<resume>/resumed/<date>/` before the app starts: a resume= that is not a run folder is named
    here first, in one line, and nothing is made in it."""
    for arg in argv:
        value = _unquoted(arg.split("=", 1)[1]) if arg.startswith("resume=") else "null"
        if value == "null":
            continue
        if not (value and Path(value).is_dir()):
            refuse(f"{arg} is not allowed: a run folder (with config.yaml and checkpoints/)")
        if not (Path(value) / "config.yaml").is_file():
            refuse(f"resume={value!r} is not a run directory: it has no config.yaml")
        if not os.access(value, os.W_OK | os.X_OK):  # Hydra's resumed/<date>/ would fail in it
            refuse(f"resume={value!r} is not allowed: the run folder cannot be written; make it writable to resume")


def check_run_dir_argument(argv: list[str]) -> None:
    """A new run into `hydra.run.dir=<a folder that holds a run>` is refused before Hydra writes its record there
    (its `.hydra/`), so the finished run's folder stays as it was; `resume=` continues a run instead."""
    resumes = [arg for arg in argv if arg.startswith("resume=") and _unquoted(arg[len("resume=") :]) != "null"]
    if resumes or any(arg in ("-m", "--multirun") for arg in argv):
        return
    for arg in argv:
        if arg.startswith("hydra.run.dir=") and (held := held_run(Path(_unquoted(arg.split("=", 1)[1])))):
            refuse(held)


def held_run(run_dir: Path) -> str | None:
    """Why a new run cannot go into `run_dir` (it holds a run's config.yaml or a checkpoint), else None."""
    if (run_dir / "config.yaml").exists() or any((run_dir / "checkpoints").glob("step_*.zip")):
        return f"{run_dir} already holds a run: continue it with resume={run_dir}, or train into another folder"
    return None


def check_group_choices(argv: list[str]) -> None:
    """Before Hydra reads the command line: every `[+]group=option` names an option that exists, else a refusal
    (`ConfigError`) in one line with the nearest option, where Hydra's own is a page of search paths. A sweep's
    comma-separated options are each checked; sweep functions (`choice(...)`) and Hydra's own groups are left to
    Hydra. A heuristic asked for as a model is pointed to `controller=`."""
    from searchrl.controllers.registry import HEURISTICS
    from searchrl.shared_schema import CONF_DIR, group_options

    for arg in argv:
        key, eq, value = arg.lstrip("+").partition("=")
        if not eq or not key or key.split("/")[0] == "hydra" or "(" in value:
            continue
        if not _is_group(key):
            continue
        options = group_options(key) + stored_options(key)
        for option in value.split(","):
            option = option.strip().strip("'\"")
            if option in options or option == "null":
                continue
            listed = ", ".join(options) if len(options) <= 12 else f"the {len(options)} files of conf/{key}/"
            if key == "model" and option in HEURISTICS:
                refuse(
                    f"{arg} is not allowed: {option} is a heuristic controller, not a model; evaluate it with "
                    f"`python -m searchrl.evaluate controller={option}`; models: {listed}"
                )
            hint = nearest(option, options, f"{key}=")
            missing = (
                f"conf/{key}/ has no {option!r}" if (CONF_DIR / key).is_dir() else f"no {key} {option!r} is registered"
            )
            refuse(f"{arg} is not allowed: {missing}{hint}; options: {listed}")


def _is_group(key: str) -> bool:
    """Whether `key` is a config group: a folder of conf/, or options a module stored (a registered reward's)."""
    from searchrl.shared_schema import CONF_DIR

    return (CONF_DIR / key).is_dir() or bool(stored_options(key))


def stored_options(group: str) -> list[str]:
    """The options of `group` a module stored in Hydra's ConfigStore (an extension's scenario, say), less the
    schemas."""
    from hydra.core.config_store import ConfigStore

    try:
        names = ConfigStore.instance().list(group)
    except OSError:  # no such group stored
        return []
    return [n.removesuffix(".yaml") for n in names if not n.removesuffix(".yaml").endswith("_schema")]


def job_variants(argv: list[str]) -> list[tuple[str, list[str]]] | None:
    """(what is checked, the overrides of one composition) for a command line: the overrides as given, each swept
    setting at its first value, then each other value of each swept setting with the rest at their first; None for
    a command line with flags other than -m. Hydra's own settings (`hydra.*`, `hydra/...`) are left out, and so are
    sweeps that cannot be listed (an Optuna interval: the sweeper draws its values)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    if any(arg.startswith("-") and arg not in _PLAIN_FLAGS for arg in argv):
        return None
    parser = OverridesParser.create()
    fixed: list[str] = []
    swept: list[tuple[str, str, list[str]]] = []  # (argument, key element, values as override text)
    for arg in argv:
        if arg in _PLAIN_FLAGS or arg.lstrip("+~").startswith("hydra"):
            continue
        try:
            override = parser.parse_override(arg)
        except Exception:  # Hydra's grammar: Hydra names what is wrong with it
            return None
        if not override.is_sweep_override():
            fixed.append(arg)
            continue
        try:
            swept.append((arg, override.get_key_element(), list(override.sweep_string_iterator())))
        except Exception:  # an interval or another sweep no list can hold
            continue
    first = [f"{key}={values[0]}" for _, key, values in swept]
    variants = [("", fixed + first)]
    for index, (arg, key, values) in enumerate(swept):
        for value in values[1:]:
            variants.append(
                (f"{key}={value} (of {arg})", fixed + first[:index] + [f"{key}={value}"] + first[index + 1 :])
            )
    return variants


def check_jobs_compose(argv: list[str], config_name: str) -> None:
    """Compose the app `config_name` (conf/<config_name>.yaml, its schemas registered) from `argv` as each of its
    `job_variants`; the first that fails is refused in one line (`ConfigError`) naming the value."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from searchrl.shared_schema import CONF_DIR

    variants = job_variants(argv)
    if variants is None:
        return
    failure = None
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3", job_name="command_line"):
        for what, overrides in variants:
            try:
                compose(config_name=config_name, overrides=overrides)
            except Exception as error:  # Hydra's ConfigCompositionException, OmegaConf's validation errors
                failure = (what, error, _misspelt_hints(compose, config_name, overrides))
                break
        hydra_args = [arg for arg in argv if arg not in _PLAIN_FLAGS and arg.lstrip("+~").startswith("hydra")]
        storage = None  # a sweeper with a study storage (Optuna's) is checked too
        if not failure and any(arg.startswith("hydra/sweeper=") for arg in hydra_args):
            storage = _sweeper_storage(compose, config_name, variants[0][1] + hydra_args)
    GlobalHydra.instance().clear()
    if storage:
        refuse(storage)
    if failure is not None:
        what, error, hints = failure
        lines = [str(error).strip()] + ([str(error.__cause__).strip()] if error.__cause__ else [])
        message = "; ".join(line.splitlines()[0] for line in lines if line)
        merging = re.match(r"Error merging override (\S+); (.*)", message)
        if merging and not what:  # the first composition: a value as given, or a sweep's first
            named, message = merging.group(1), merging.group(2)
            key = named.partition("=")[0]
            of = [arg for arg in argv if arg.partition("=")[0] == key and arg != named]
            what = f"{named} (of {of[0]})" if of else named
        elif merging:
            message = merging.group(2)
        unknown = re.match(r"Could not override '([^']+)'\.?; (.*)", message)
        if unknown:
            given = [arg for arg in argv if arg.lstrip("+~").partition("=")[0] == unknown.group(1)]
            what, message = what or (given[0] if given else unknown.group(1)), unknown.group(2)
        missing = re.match(r"Key '([^']+)' not in '[^']+'", message)
        if missing and missing.group(1) in hints:  # a misspelt setting, worded as schema.unknown_keys words it
            message = "no such setting" + hints[missing.group(1)]
        refuse(f"{what or 'the command line'} is not allowed: {message}")


def _sweeper_storage(compose, config_name: str, overrides: list[str]) -> str | None:
    """Why the sweeper's `storage` (Optuna's study database) cannot be opened, or None: a SQLite file whose folder
    does not exist or cannot be written fails only when the sweep starts, in a traceback of SQLAlchemy's."""
    from omegaconf import OmegaConf

    try:
        url = OmegaConf.select(
            compose(config_name=config_name, overrides=overrides, return_hydra_config=True),
            "hydra.sweeper.storage",
            default=None,
        )
    except Exception:  # a composition error is the compose check's to name
        return None
    if not isinstance(url, str) or not url.startswith("sqlite:///"):
        return None  # no storage (an in-memory study), or a server the sweep connects to itself
    folder = Path(url.removeprefix("sqlite:///")).parent
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        why = "does not exist" if not folder.is_dir() else "cannot be written"
        return (
            f"hydra.sweeper.storage={url!r} is not allowed: its folder {str(folder)!r} {why} (the study's "
            "SQLite file is made there)"
        )
    return None


def _misspelt_hints(compose, config_name: str, overrides: list[str]) -> dict[str, str]:
    """{leaf: its `schema.nearest` hint} for each override `a.b.leaf=v` whose key the config composed without it
    lacks (a misspelt setting: Hydra says only "Key 'leaf' not in 'Schema'"); {} if that config does not compose."""
    from omegaconf import DictConfig, OmegaConf

    keys = [
        o.partition("=")[0]
        for o in overrides  # settings, not the group choices that shape the config
        if "=" in o and not o.startswith(("+", "~")) and not _is_group(o.partition("=")[0])
    ]
    try:
        cfg = compose(config_name=config_name, overrides=[o for o in overrides if o.partition("=")[0] not in keys])
    except Exception:
        return {}
    hints: dict[str, str] = {}
    for key in keys:
        parent, _, leaf = key.rpartition(".")
        node = OmegaConf.select(cfg, parent) if parent else cfg
        if isinstance(node, DictConfig) and leaf not in node:
            hints[leaf] = nearest(leaf, [str(k) for k in node], f"{parent}." if parent else "")
    return hints
