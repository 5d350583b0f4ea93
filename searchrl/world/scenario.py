"""Scenarios: what a reset draws besides the §4.1 sizes — the obstacles, and where the truth puts the targets.

Spec. A reset of world k draws, from its generator and in this order (searchrl/world/reset.py):
1. the side n, Gaussian count m and target count j from WorldConfig's ranges (§4.1.2-4.1.4);
2. the prior maps p and u the agents start from (§4.1.3: mixtures of Gaussians, eq. 6-8);
3. the obstacles, `scenario.obstacles(n, room, rng)`: (n, n) bool or None; p and u are renormalised over free cells;
4. the targets, `scenario.targets(p, u, free, j, rng)`: (j, 2) distinct free cells, where the truth puts them
   (searchrl/world/truth.py: the paper's placement and the families of prior error);
5. the agents' start cells, uniformly on the free cells left.

A `Scenario` is those two injected parts (Jumanji's `Generator`, split where scenarios vary). Its default, the
paper's, is `Scenario(IidObstacles(0.0), PriorTargets())`: no obstacle, targets from the prior; neither draws
anything the paper's reset did not, so its worlds are those of every run made before scenarios existed, bit for bit.
The sizes and the prior's law stay in WorldConfig: they are the grid's axes (an evaluation sets them per cell) and
bound the arrays a world allocates; a scenario changes what stands on the grid and how the truth relates to the prior.

A scenario is chosen by name in Hydra (`scenario=walls`, conf/scenario/) and read from a plain mapping
(`Scenario.from_dict`, the form a run's config.yaml and an evaluation record keep); its `label` names it in every
result row, derived from its values so two different scenarios never share one.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any, ClassVar, Protocol

import numpy as np

from searchrl.world.config import ConfigError, WorldConfig, need
from searchrl.world.truth import PLACERS, PriorTargets, finite, keep_probability, place_targets  # noqa: F401 (imported from here too)

_MAX_OBSTACLE_DRAWS = 100


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


@dataclass(frozen=True)
class IidObstacles:
    """Each cell an obstacle with probability `density`, independently (n × n uniforms); the draw is repeated until
    `room` cells stay free (agents and targets need distinct free cells). Density 0 draws nothing."""

    kind: ClassVar[str] = "iid"
    density: float = 0.0

    def __call__(self, n: int, room: int, rng: np.random.Generator) -> np.ndarray | None:
        """(n, n) bool, True on obstacles, or None without obstacles."""
        if self.density <= 0:
            return None
        for _ in range(_MAX_OBSTACLE_DRAWS):
            obstacles = rng.random((n, n)) < self.density
            if (~obstacles).sum() >= room:
                return obstacles
        raise RuntimeError(f"{_MAX_OBSTACLE_DRAWS} obstacle draws at density {self.density} left fewer than "
                           f"{room} free cells of {n}x{n}")  # fmt: skip

    def check(self, config: WorldConfig) -> None:
        need(finite(self.density) and 0 <= self.density < 1, "scenario.obstacles.density", self.density,
             "0 <= density < 1")  # fmt: skip
        # Agents and targets need distinct free cells in the smallest world: checked at the expected density here,
        # exactly at every reset (the draw repeats until they fit).
        n = config.world_size[0]
        free = int(n * n * (1.0 - self.density))
        room = config.n_agents + config.n_targets[1]
        need(room <= free, "scenario.obstacles.density", self.density,
             f"agents and targets start on distinct cells: n_agents + max targets = {room} must fit the {free} free "
             f"cells of the smallest world (n={n}) at this density")  # fmt: skip

    @property
    def label(self) -> str:
        return f"iid{self.density:g}" if self.density > 0 else ""


OBSTACLES: dict[str, type] = {cls.kind: cls for cls in (IidObstacles,)}
TARGETS: dict[str, type] = PLACERS  # searchrl/world/truth.py


@dataclass(frozen=True)
class Scenario:
    """What a reset draws besides the §4.1 sizes and prior (module docstring); the default is the paper's."""

    obstacles: ObstacleGenerator = field(default_factory=IidObstacles)
    targets: TargetPlacer = field(default_factory=PriorTargets)

    @property
    def label(self) -> str:
        """ "paper" for the paper's scenario, else its parts' labels joined by "+" (e.g. "iid0.2+off_prior0.5")."""
        parts = [part for part in (self.obstacles.label, self.targets.label) if part]
        return "+".join(parts) or "paper"

    @property
    def targets_follow_prior(self) -> bool:
        """Targets placed by §4.1.4's law from the prior the agents hold (what the search bound assumes): the
        paper's placement, or a family of prior error at severity 0."""
        return self.targets.follows_prior

    def check(self, config: WorldConfig) -> None:
        """ConfigError naming the first value this scenario cannot draw in `config`'s worlds."""
        self.obstacles.check(config)
        self.targets.check(config)

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """The plain mapping `from_dict` reads: {"obstacles": {"kind": …, …}, "targets": {"kind": …, …}}."""
        return {name: {"kind": part.kind, **asdict(part)} for name, part in (("obstacles", self.obstacles),
                                                                            ("targets", self.targets))}  # fmt: skip

    @classmethod
    def from_dict(cls, values: dict | None) -> Scenario:
        """Read `to_dict`'s form (a Hydra node, a run's config.yaml); None or {} is the paper's. ConfigError naming
        an unknown part, kind or setting."""
        values = dict(values or {})
        unknown = sorted(set(values) - {"obstacles", "targets"})
        if unknown:
            raise ConfigError(f"scenario.{unknown[0]} is not allowed: a scenario has obstacles and targets")
        parts = {}
        for name, kinds in (("obstacles", OBSTACLES), ("targets", TARGETS)):
            settings = dict(values.get(name) or {})
            kind = settings.pop("kind", next(iter(kinds)))
            need(kind in kinds, f"scenario.{name}.kind", kind, f"one of {', '.join(kinds)}")
            allowed = {f.name for f in fields(kinds[kind])}
            extra = sorted(set(settings) - allowed)
            if extra:
                raise ConfigError(f"scenario.{name}.{extra[0]}={settings[extra[0]]!r} is not allowed: "
                                  f"{name} of kind {kind} take {sorted(allowed) or 'no settings'}")  # fmt: skip
            parts[name] = kinds[kind](**settings)
        return cls(**parts)


PAPER = Scenario()
