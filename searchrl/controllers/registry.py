"""The one registry of heuristic controllers: a name -> its class and its settings dataclass (the schema).

Every entry point reads it: evaluation (`controller=<name>`, conf/controller/<name>.yaml), imitation
(`imitation.teacher=<name>`), `python -m searchrl.render --controller <name>` and
`python -m searchrl.bench eval --controller <name>`; their error messages list its names. Each schema lives beside
its class (searchrl/controllers/*.py); the Hydra layer registers it as `<name>_schema`
(searchrl/evaluate/schema.py). Trained policies are not here: they come from a checkpoint (policy.py).

A name may be a preset of another controller's settings: `greedy_target` is footprint-greedy with horizon 3 and
w_p = w_u = 0, w_t = 1. Its results are recorded under the controller's `label` ("greedy", with those settings),
so an evaluation folder made with the settings spelled out (`controller=greedy controller.horizon=3 ...`) and one
made with `controller=greedy_target` hold the same record and take each other's reruns.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, fields
from typing import Any

from searchrl.controllers.base import Controller, ControllerConfig, RandomConfig, RandomWalk
from searchrl.controllers.coverage import CoverageConfig, GeometricCoverage
from searchrl.controllers.greedy import FootprintGreedy, GreedyConfig, GreedyTargetConfig
from searchrl.controllers.rollout import Rollout, RolloutConfig
from searchrl.controllers.surfing import InformationSurfing, SurfingConfig
from searchrl.controllers.switch import EvidenceSwitch, SwitchConfig
from searchrl.controllers.walls import PathGreedy, PathGreedyConfig, SweepConfig, SweepCoverage
from searchrl.registry import Registry, typed_settings
from searchrl.world.config import ConfigError, WorldConfig, in_context
from searchrl.world.streams import WorldStreams


@dataclass(frozen=True)
class Heuristic:
    """A registered controller: `cls(config, **settings[, seed=])`, its settings' dataclass, the name its results
    are recorded under (evaluation.yaml's and every result row's `controller`), and whether it may teach
    (`imitation.teacher=`)."""

    cls: type
    schema: type[ControllerConfig]
    label: str
    teacher: bool = True

    def settings(self) -> dict[str, Any]:
        """The schema's defaults without `name`: the keyword arguments of `cls` besides the world and the seed."""
        return keyword_settings(self.schema())


HEURISTICS: Registry[Heuristic] = Registry(
    "controller",
    {
        "surfing": Heuristic(InformationSurfing, SurfingConfig, "surfing"),
        "greedy": Heuristic(FootprintGreedy, GreedyConfig, "greedy"),
        "greedy_target": Heuristic(FootprintGreedy, GreedyTargetConfig, "greedy"),
        "coverage": Heuristic(GeometricCoverage, CoverageConfig, "coverage"),
        "switch": Heuristic(EvidenceSwitch, SwitchConfig, "switch"),
        "path_greedy": Heuristic(PathGreedy, PathGreedyConfig, "path_greedy"),
        "sweep": Heuristic(SweepCoverage, SweepConfig, "sweep"),
        "random": Heuristic(RandomWalk, RandomConfig, "random", teacher=False),
        "rollout": Heuristic(Rollout, RolloutConfig, "rollout"),
    },
)


def resolved(name: str, settings: dict[str, Any] | None = None) -> tuple[str, dict[str, Any]]:
    """(the name results are recorded under, every setting) of controller `name` with `settings`: a preset and the
    same settings spelled out give the same pair (`greedy_target` with reach 2 is `greedy` with horizon 3, w_p 0,
    w_u 0, w_t 1 and reach 2); numbers take their field's type (a YAML's 0 is the float 0.0 of w_p)."""
    return heuristic(name).label, keyword_settings(controller_settings(name, settings))


def allowed() -> str:
    """The registered names, comma-separated, for error messages."""
    return ", ".join(HEURISTICS)


def heuristic(name: object, key: str = "controller", other: str = "") -> Heuristic:
    """The entry of `name`; ConfigError "`key`=name is not allowed: one of …" listing the registered names (and
    `other`)."""
    return HEURISTICS.lookup(name, key, other)


def make_controller(
    name: str,
    config: WorldConfig,
    seed: int | WorldStreams = 0,
    settings: dict[str, Any] | None = None,
    key: str = "controller",
) -> Controller:
    """The controller `name` in the world `config` with `settings` (`controller_settings`), seeded with `seed` where
    it draws random moves (`build_controller`). ConfigError for an unknown name (naming `key`), an unknown setting,
    a value of another type than its field's, or one the class refuses."""
    return build_controller(controller_settings(name, settings, key), config, seed)


def controller_settings(name: str, settings: dict[str, Any] | None = None, key: str = "controller") -> ControllerConfig:
    """The settings dataclass of heuristic `name` (a `ControllerConfig`): its defaults, overridden by `settings`
    (plain values without `name`, each checked against its field's type: `typed_settings`). ConfigError for an
    unknown name (naming `key`), an unknown setting or a value of another type."""
    entry = heuristic(name, key)
    values = entry.settings()
    unknown = sorted(set(settings or {}) - set(values))
    if unknown:
        raise ConfigError(f"{name} takes no setting {unknown[0]!r}; its settings are {sorted(values)}")
    values.update(typed_settings(entry.schema, dict(settings or {}), key))
    return entry.schema(**{**values, "name": name})


def build_controller(chosen: ControllerConfig, config: WorldConfig, seed: int | WorldStreams = 0) -> Controller:
    """The heuristic `chosen` names, built from those settings in the world `config`, seeded with `seed` where it
    draws random moves; a controller that plays other rules (the rollout planner's base) gets `make_controller`
    as `rules`. ConfigError for a value its class refuses (a user's class saying so with a ValueError too)."""
    entry = heuristic(chosen.name)
    values = keyword_settings(chosen)
    parameters = inspect.signature(entry.cls).parameters
    if "seed" in parameters:
        values["seed"] = seed
    if "rules" in parameters:
        values["rules"] = make_controller
    try:
        return entry.cls(config, **values)
    except ConfigError:
        raise
    except ValueError as err:  # a user's rule refusing a value its own way: said as the refusal it is
        raise ConfigError(f"{chosen.name}: {err}") from None


def keyword_settings(chosen: ControllerConfig) -> dict[str, Any]:
    """A heuristic's settings dataclass as its class's keyword arguments: every field but `name`."""
    return {f.name: getattr(chosen, f.name) for f in fields(chosen) if f.name != "name"}


def teachers() -> tuple[str, ...]:
    """The heuristics `imitation.teacher=` may name (all but random, and those registered with `teacher=False`)."""
    return tuple(name for name, entry in HEURISTICS.items() if entry.teacher)


def register(name: str, cls: type, schema: type, label: str | None = None, teacher: bool = True) -> None:
    """Add a heuristic: `controller=name` of the apps, and `imitation.teacher=name` with `teacher`. `cls(config,
    **settings[, seed])` makes it (the `Controller` protocol, searchrl/controllers/base.py); `schema` is its
    settings' dataclass (a `ControllerConfig` whose `name` is `name`); `label` is the name its results are
    recorded under (default `name`). The same registered again is accepted; ConfigError for a name another holds."""
    HEURISTICS.register(name, Heuristic(cls, schema, label or name, teacher))


def teacher_settings(teacher: str, args: dict[str, Any] | None = None) -> ControllerConfig:
    """The settings dataclass of `imitation.teacher` with `imitation.teacher_args` (`controller_settings`), what
    the imitation layer builds its teachers from; ConfigError naming either if it is not allowed (an unknown or
    random teacher, an argument its controller does not take or of another type, a seed)."""
    if teacher not in teachers():
        raise ConfigError(f"imitation.teacher={teacher!r} is not allowed: one of {', '.join(teachers())}, or null")
    args = dict(args or {})
    if "seed" in args:
        raise ConfigError("imitation.teacher_args.seed is not allowed: the teacher is seeded from the run's seed")
    with in_context(f"imitation.teacher_args={args} is not allowed for teacher {teacher!r}"):
        return controller_settings(teacher, args, "imitation.teacher_args")


def make_teacher(teacher: ControllerConfig, config: WorldConfig, seed: int | WorldStreams) -> Controller:
    """The teacher's controller (`teacher_settings`) in the world `config`, seeded with `seed`; ConfigError naming
    `imitation.teacher_args` for a value its class refuses."""
    with in_context(f"imitation.teacher_args of teacher {teacher.name!r}"):
        return build_controller(teacher, config, seed)
