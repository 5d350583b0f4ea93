"""Scenarios: what a reset draws besides the §4.1 sizes — the obstacles, and where the truth puts the targets.

Spec. A reset of world k draws, from its generator and in this order (searchrl/world/reset.py):
1. the side n, Gaussian count m and target count j from WorldConfig's ranges (§4.1.2-4.1.4);
2. the prior maps p and u the agents start from (§4.1.3: mixtures of Gaussians, eq. 6-8);
3. the obstacles, `scenario.obstacles(n, room, rng)`: (n, n) bool or None; p and u are renormalised over free cells;
4. the targets, `scenario.targets(p, u, free, j, rng)`: (j, 2) distinct free cells, where the truth puts them;
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

from searchrl.world.config import ConfigError, WorldConfig, is_int, need

_MAX_OBSTACLE_DRAWS = 100
_MAX_TARGET_ROUNDS = 1_000


def keep_probability(u: np.ndarray) -> np.ndarray:
    """The second stage of §4.1.4's placement: a tentative cell is kept with probability 1 - u/max(u) (the paper's
    `1 - u` needs u on a [0, 1] scale and u sums to 1, so we read it relative to its maximum). Same shape as u."""
    return 1.0 - u / u.max()


def place_targets(p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """Two-stage placement of §4.1.4 on distinct free cells.

    A tentative cell is drawn from p over the free cells, then kept when a uniform draw is below
    `keep_probability(u)`. A tentative cell that already holds a target is redrawn (rejection from p restricted
    to empty cells). Candidates are drawn in batches of `4 · count` from one CDF. p, u, free: (n, n).
    Returns (count, 2) int64 (row, col).
    """
    if count == 0:
        return np.zeros((0, 2), np.int64)
    n = p.shape[0]
    cdf = np.cumsum(np.where(free, p, 0.0).ravel())
    keep_prob = keep_probability(u).ravel()
    chosen: list[int] = []
    taken: set[int] = set()
    for _ in range(_MAX_TARGET_ROUNDS):
        batch = 4 * count
        cells = np.minimum(np.searchsorted(cdf, rng.random(batch) * cdf[-1], side="right"), n * n - 1)
        keep = rng.random(batch) < keep_prob[cells]
        for cell in cells[keep].tolist():
            if cell not in taken:
                taken.add(cell)
                chosen.append(cell)
                if len(chosen) == count:
                    return np.stack(np.divmod(np.array(chosen, np.int64), n), axis=1)
    raise RuntimeError(f"could not place {count} targets in {_MAX_TARGET_ROUNDS} batches (maps too peaked?)")


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


def _finite(value: object) -> bool:
    return (is_int(value) or isinstance(value, (float, np.floating))) and np.isfinite(value)


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
        need(_finite(self.density) and 0 <= self.density < 1, "scenario.obstacles.density", self.density,
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


@dataclass(frozen=True)
class PriorTargets:
    """§4.1.4: targets placed from the prior itself (`place_targets`, the paper's two-stage law)."""

    kind: ClassVar[str] = "prior"

    def __call__(self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator
                 ) -> np.ndarray:  # fmt: skip
        return place_targets(p, u, free, count, rng)

    def check(self, config: WorldConfig) -> None:
        pass

    @property
    def label(self) -> str:
        return ""


@dataclass(frozen=True)
class OffPriorTargets:
    """Targets off the prior: each of the j targets, independently with probability `severity`, lies uniformly on
    a free cell instead of following §4.1.4's law; the agents still start from the prior. Severity 0 is the paper's
    placement, drawn exactly as `PriorTargets` draws it; severity 1 places every target uniformly (the prior says
    nothing about where they are). Draws: j uniforms (which targets are off), the prior's placement of the others,
    then the off targets' cells without replacement among the free cells left."""

    kind: ClassVar[str] = "off_prior"
    severity: float = 1.0

    def __call__(self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator
                 ) -> np.ndarray:  # fmt: skip
        if self.severity == 0:
            return place_targets(p, u, free, count, rng)
        off = int((rng.random(count) < self.severity).sum())
        placed = place_targets(p, u, free, count - off, rng) if off < count else np.zeros((0, 2), np.int64)
        left = free.copy()
        left[placed[:, 0], placed[:, 1]] = False
        cells = rng.choice(np.flatnonzero(left.ravel()), size=off, replace=False).astype(np.int64)
        return np.concatenate([placed, np.stack(np.divmod(cells, free.shape[0]), axis=1)])

    def check(self, config: WorldConfig) -> None:
        need(_finite(self.severity) and 0 <= self.severity <= 1, "scenario.targets.severity", self.severity,
             "0 <= severity <= 1 (the share of targets placed uniformly instead of from the prior)")  # fmt: skip

    @property
    def label(self) -> str:
        return f"off_prior{self.severity:g}"


OBSTACLES: dict[str, type] = {cls.kind: cls for cls in (IidObstacles,)}
TARGETS: dict[str, type] = {cls.kind: cls for cls in (PriorTargets, OffPriorTargets)}


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
        """Targets placed by §4.1.4's law from the prior the agents hold (what the search bound assumes)."""
        return self.targets.label == ""

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
