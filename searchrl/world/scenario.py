"""Scenarios: what a reset draws besides the §4.1 sizes — the obstacles, and where the truth puts the targets.

Spec. A reset of world k draws, from its generator and in this order (searchrl/world/reset.py):
1. the side n, Gaussian count m and target count j from WorldConfig's ranges (§4.1.2-4.1.4);
2. the maps, `scenario.prior(config, n, m, rng)`: the prior p and u the agents start from (§4.1.3: mixtures of
   Gaussians, eq. 6-8) and the truth's maps, the prior itself in the paper (searchrl/world/prior.py: sharper priors,
   mis-weighted modes, agents that know less);
3. the obstacles, `scenario.obstacles(n, room, rng)`: (n, n) bool or None; every map is renormalised over free cells;
4. the targets, `scenario.targets(truth_p, truth_u, free, j, rng)`: (j, 2) distinct free cells, where the truth puts
   them (searchrl/world/truth.py: the paper's placement and the families of prior error);
5. the agents' start cells, uniformly on the free cells left.

A `Scenario` is those three injected parts (Jumanji's `Generator`, split where scenarios vary). Its default, the
paper's, is `Scenario(IidObstacles(0.0), PriorTargets(), MixturePrior())`: no obstacle, the world's prior, targets
from it; none draws anything the paper's reset did not, so its worlds are those of every run made before scenarios
existed, bit for bit. The sizes and the prior's constants stay in WorldConfig: they are the grid's axes (an
evaluation sets them per cell) and bound the arrays a world allocates; a scenario changes what stands on the grid,
how sharp the prior is and how the truth relates to it, and applies to a trained policy's world unchanged.

A scenario is chosen by name in Hydra (`scenario=walls`, conf/scenario/) and read from a plain mapping
(`Scenario.from_dict`, the form a run's config.yaml and an evaluation record keep); its `label` names it in every
result row, derived from its values so two different scenarios never share one.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass, field, fields
from typing import Any, ClassVar, Protocol

import numpy as np

from searchrl.registry import Registry
from searchrl.world.config import ConfigError, WorldConfig, need
from searchrl.world.obstacles import OBSTACLES, IidObstacles
from searchrl.world.prior import PRIORS, MixturePrior, PriorDraw
from searchrl.world.truth import PLACERS, PriorTargets, finite, keep_probability, place_targets  # noqa: F401 (imported from here too)


class ObstacleGenerator(Protocol):
    kind: ClassVar[str]

    def __call__(self, n: int, room: int, rng: np.random.Generator) -> np.ndarray | None: ...

    def check(self, config: WorldConfig) -> None: ...

    @property
    def label(self) -> str: ...


class TargetPlacer(Protocol):
    kind: ClassVar[str]

    def __call__(
        self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator
    ) -> np.ndarray: ...

    def check(self, config: WorldConfig) -> None: ...

    @property
    def label(self) -> str: ...

    @property
    def follows_prior(self) -> bool: ...


class PriorGenerator(Protocol):
    kind: ClassVar[str]

    def __call__(self, config: WorldConfig, n: int, m: int, rng: np.random.Generator) -> PriorDraw: ...

    def check(self, config: WorldConfig) -> None: ...

    @property
    def label(self) -> str: ...

    @property
    def truth_is_prior(self) -> bool: ...


TARGETS: Registry[type] = PLACERS  # searchrl/world/truth.py
PARTS: dict[str, Registry[type]] = {"obstacles": OBSTACLES, "prior": PRIORS, "targets": TARGETS}


def register_part(part: str, cls: type) -> None:
    """Add a scenario part: `scenario.<part>.kind=<cls.kind>` with `cls`'s dataclass fields as its settings, in
    every app and mix. `cls` is a frozen dataclass implementing the part's protocol above (ObstacleGenerator,
    TargetPlacer or PriorGenerator). ConfigError for an unknown part or a kind another class holds."""
    need(part in PARTS, "part", part, f"one of {', '.join(PARTS)}")
    PARTS[part].register(part=cls)


@dataclass(frozen=True)
class Scenario:
    """What a reset draws besides the §4.1 sizes and prior (module docstring); the default is the paper's."""

    obstacles: ObstacleGenerator = field(default_factory=IidObstacles)
    targets: TargetPlacer = field(default_factory=PriorTargets)
    prior: PriorGenerator = field(default_factory=MixturePrior)

    @property
    def parts(self) -> tuple[tuple[str, Any], ...]:
        return ("obstacles", self.obstacles), ("prior", self.prior), ("targets", self.targets)

    @property
    def label(self) -> str:
        """ "paper" for the paper's scenario, else its parts' labels joined by "+" (e.g. "iid0.2+off_prior0.5",
        "var1+misweighted1")."""
        return "+".join(part.label for _, part in self.parts if part.label) or "paper"

    @property
    def family(self) -> str:
        """The families of prior error this scenario draws with a severity above 0, joined by "+", or "paper"."""
        wrong = [part.family for _, part in self.parts if getattr(part, "severity", 0) > 0]
        return "+".join(wrong) or "paper"

    @property
    def severity(self) -> float:
        """The largest severity of its families of prior error (0: the prior is right)."""
        return max([float(getattr(part, "severity", 0.0)) for _, part in self.parts])

    @property
    def targets_follow_prior(self) -> bool:
        """Targets placed by §4.1.4's law from the prior the agents hold (what the search bound assumes): the
        paper's placement from the prior's own maps, or a family of prior error at severity 0."""
        return self.targets.follows_prior and self.prior.truth_is_prior

    def check(self, config: WorldConfig) -> None:
        """ConfigError naming the first value this scenario cannot draw in `config`'s worlds."""
        for _, part in self.parts:
            part.check(config)

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """The plain mapping `from_dict` reads: {"obstacles": {"kind": …, …}, "prior": …, "targets": …}."""
        return {name: {"kind": part.kind, **asdict(part)} for name, part in self.parts}

    def pick(self, rng: np.random.Generator) -> Scenario:
        """The scenario a reset draws from: this one (nothing drawn; a `ScenarioMix` draws one of its own)."""
        return self

    @classmethod
    def from_dict(cls, values: dict | None) -> Scenario | ScenarioMix:
        """Read `to_dict`'s form (a Hydra node, a run's config.yaml), or a mix's (`{"mix": {...}}`, its other parts
        null); None or {} is the paper's. ConfigError naming an unknown part, kind or setting."""
        values = dict(values or {})
        if values.get("mix") is not None:
            given = sorted(k for k, v in values.items() if k != "mix" and v is not None)
            if given:
                raise ConfigError(
                    f"scenario.{given[0]} is not allowed with scenario.mix: a mix draws whole "
                    "scenarios (set the part in its families, or null it)"
                )
            return ScenarioMix.from_spec(values["mix"])
        values = {k: v for k, v in values.items() if k != "mix"}
        unknown = sorted(set(values) - {"obstacles", "prior", "targets"})
        if unknown:
            raise ConfigError(
                f"scenario.{unknown[0]} is not allowed: a scenario has obstacles, prior and targets (or a mix)"
            )
        parts = {}
        for name, kinds in PARTS.items():
            settings = dict(values.get(name) or {})
            kind = settings.pop("kind", next(iter(kinds)))
            allowed = {f.name for f in fields(kinds.lookup(kind))}
            extra = sorted(set(settings) - allowed)
            if extra:
                raise ConfigError(
                    f"scenario.{name}.{extra[0]}={settings[extra[0]]!r} is not allowed: "
                    f"{name} of kind {kind} take {sorted(allowed) or 'no settings'}"
                )
            parts[name] = kinds[kind](**settings)
        return cls(**parts)


PAPER = Scenario()


def scenario_grid(
    families: dict[str, dict],
    severities: list[float],
    variance_scales: list[float | None],
    obstacles: dict | None = None,
    name: str = "suite",
) -> list[Scenario]:
    """Scenarios made from families of prior error: per variance scale (the prior's sharpness, null: the world's),
    the prior right (severity 0), then each family at each severity. `families` maps a name to the parts the
    family sets ({"targets": {"kind": "shifted"}}), each part's severity set per point. ConfigError naming a bad
    value under `name` (the suite's or the mix's key)."""
    severities = [float(s) for s in severities]
    need(
        (len(severities) > 0 or not families) and all(0 < s <= 1 for s in severities),
        f"{name}.severities",
        severities,
        "severities in (0, 1] (severity 0, the prior right, comes once per sharpness)",
    )
    need(len(variance_scales) > 0, f"{name}.variance_scales", variance_scales, "one or more (null: the world's)")
    scenarios = []
    for scale in variance_scales:
        base: dict[str, Any] = {"prior": {"kind": "mixture", "variance_scale": scale}}
        if obstacles:
            base["obstacles"] = dict(obstacles)
        scenarios.append(Scenario.from_dict(base))
        for family, parts in families.items():
            need(
                isinstance(parts, dict) and bool(parts) and set(parts) <= {"prior", "targets"},
                f"{name}.families.{family}",
                parts,
                "the parts the family sets: prior and/or targets, with a kind",
            )
            for severity in severities:
                values = {
                    **base,
                    **{
                        part: {**base.get(part, {}), **settings, "severity": severity}
                        for part, settings in parts.items()
                    },
                }
                values["prior"] = {**values["prior"], "variance_scale": scale}
                scenarios.append(Scenario.from_dict(values))
    return scenarios


@dataclass(frozen=True)
class ScenarioMix:
    """A training distribution over scenarios (`scenario.mix`: families, severities, variance_scales, obstacles as
    `scenario_grid` takes them, and explicit `scenarios`): each reset draws one integer from the world's generator,
    before anything else, to pick a family (the prior right and each explicit scenario counting as one) and a
    severity uniformly, then that scenario's world."""

    scenarios: tuple[Scenario, ...]
    spec: tuple[tuple[str, Any], ...]  # the mapping it was made from, as `to_dict` gives it back

    @classmethod
    def from_spec(cls, spec: dict) -> ScenarioMix:
        spec = dict(spec)
        unknown = sorted(set(spec) - {"families", "severities", "variance_scales", "obstacles", "scenarios"})
        if unknown:
            raise ConfigError(
                f"scenario.mix.{unknown[0]} is not allowed: a mix has families, severities, "
                "variance_scales, obstacles and scenarios"
            )
        severities = list(spec.get("severities") or [])
        grid = scenario_grid(
            dict(spec.get("families") or {}),
            severities,
            list(spec.get("variance_scales") or [None]),
            spec.get("obstacles"),
            name="scenario.mix",
        )
        per_scale = 1 + len(spec.get("families") or {}) * len(severities)
        weighted = []  # the right prior repeated once per severity: a family, picked as often as each other
        for start in range(0, len(grid), per_scale):
            weighted += [grid[start]] * max(1, len(severities)) + grid[start + 1 : start + per_scale]
        # explicit scenarios (an obstacle kind each, say), each picked as often as a family
        weighted += [
            s for values in spec.get("scenarios") or [] for s in [Scenario.from_dict(values)] * max(1, len(severities))
        ]
        return cls(tuple(weighted), tuple(sorted(spec.items())))

    def pick(self, rng: np.random.Generator) -> Scenario:
        return self.scenarios[int(rng.integers(len(self.scenarios)))]

    def check(self, config: WorldConfig) -> None:
        for scenario in dict.fromkeys(self.scenarios):
            scenario.check(config)

    def to_dict(self) -> dict[str, Any]:
        return {"mix": dict(self.spec)}

    @property
    def label(self) -> str:
        """ "mix-" and a hash of its scenarios' labels: two different mixes never share one."""
        digest = hashlib.sha256(",".join(s.label for s in self.scenarios).encode()).hexdigest()[:8]
        return f"mix-{digest}"

    @property
    def family(self) -> str:
        return "mix"

    @property
    def severity(self) -> float:
        return float("nan")

    @property
    def targets_follow_prior(self) -> bool:
        return all(s.targets_follow_prior for s in self.scenarios)
