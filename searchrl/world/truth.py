"""Where the truth puts the targets: the paper's placement (§4.1.4) and families of prior error.

Every placer is called as `placer(p, u, free, count, rng) -> (count, 2) int64` distinct free cells, where p and u
(n, n) are the prior the agents start from and `free` (n, n) bool the cells without obstacles. A family of prior
error has a severity s in [0, 1]: s = 0 is the paper's placement, drawn exactly as `PriorTargets` draws it (the
same cells and nothing more drawn from `rng`), and s grows with how wrong the prior is:

- `OffPriorTargets` (off_prior): each target, with probability s, uniformly on a free cell instead;
- `ShiftedTargets` (shifted): the truth is the prior translated by s · `distance` · n cells in a direction drawn
  uniformly (the map wraps around the edges, so no mass is lost), and the targets follow the translated maps;
- `TemperedTargets` (sharper, flatter): the truth is p^a renormalised, a = 1 + s·(`power` − 1): `power` > 1 makes
  the truth sharper than the prior (its modes hold more of the targets), `power` < 1 flatter (0: uniform in p);
- `AdversarialTargets` (adversarial): each target, with probability s, placed from the prior turned upside down
  (its masses given to the cells in reverse order of p): where the prior says the targets are least likely.

`prior_quality` measures, per world, how well the prior the agents hold points at the true targets (MapScore-like).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from searchrl.registry import Registry
from searchrl.world.config import WorldConfig, is_int, need
from searchrl.world.kernels import CACHE
from searchrl.world.libm import power
from searchrl.world.state import WorldState

_MAX_TARGET_ROUNDS = 1_000


def keep_probability(u: np.ndarray) -> np.ndarray:
    """The second stage of §4.1.4's placement: a tentative cell is kept with probability 1 - u/max(u) (the paper's
    `1 - u` needs u on a [0, 1] scale and u sums to 1, so we read it relative to its maximum). Same shape as u."""
    return 1.0 - u / u.max()


def place_targets(p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """Two-stage placement of §4.1.4 on distinct free cells.

    A tentative cell is drawn from p over the free cells, then kept when a uniform draw is below
    `keep_probability(u)`. A tentative cell that already holds a target is redrawn (rejection from p restricted
    to empty cells). Candidates are drawn in batches of `4 · count` from one CDF: a batch's two sets of uniforms
    are drawn here, its cells chosen in one compiled call (`_place_batch`). p, u, free: (n, n).
    Returns (count, 2) int64 (row, col).
    """
    if count == 0:
        return np.zeros((0, 2), np.int64)
    n = p.shape[0]
    cdf, keep_prob = _placement_tables(np.asarray(p, np.float64), np.asarray(u, np.float64), np.asarray(free, bool))
    chosen, taken, placed = np.empty(count, np.int64), np.zeros(n * n, np.bool_), 0
    for _ in range(_MAX_TARGET_ROUNDS):
        batch = 4 * count
        placed = _place_batch(cdf, keep_prob, rng.random(batch), rng.random(batch), taken, chosen, placed)
        if placed == count:
            return rows_cols(chosen, n)
    raise RuntimeError(f"could not place {count} targets in {_MAX_TARGET_ROUNDS} batches (maps too peaked?)")


@njit(cache=CACHE)
def _placement_tables(p, u, free):
    """(cdf, keep) (n²,) float64 of p, u and free (n, n): the running sum of p over the free cells, row by row
    (numpy's cumsum of where(free, p, 0), the same bits), and `keep_probability(u)` flattened."""
    n = p.shape[0]
    cdf, keep = np.empty(n * n), np.empty(n * n)
    total, peak = 0.0, u.max()
    for r in range(n):
        for c in range(n):
            total += p[r, c] if free[r, c] else 0.0
            cdf[r * n + c] = total
            keep[r * n + c] = 1.0 - u[r, c] / peak
    return cdf, keep


@njit(cache=CACHE)
def rows_cols(cells, n):
    """(len, 2) int64: the (row, col) of each of the flat indices cells (len,) int64 of an n×n grid."""
    out = np.empty((cells.shape[0], 2), np.int64)
    for i in range(cells.shape[0]):
        out[i, 0], out[i, 1] = cells[i] // n, cells[i] % n
    return out


@njit(cache=CACHE)
def _place_batch(cdf, keep, at, keep_draw, taken, chosen, placed):
    """One batch of `place_targets`: candidate b is the cell where `at[b]` · total falls in cdf (numpy's
    searchsorted, side right, capped at the last cell), kept when keep_draw[b] < keep[cell] and not `taken`;
    kept cells go to chosen (count,) int64 after the `placed` already there, until it is full. Returns the count
    placed."""
    last, total = cdf.shape[0] - 1, cdf[-1]
    for b in range(at.shape[0]):
        cell = min(np.searchsorted(cdf, at[b] * total, side="right"), last)
        if keep_draw[b] < keep[cell] and not taken[cell]:
            taken[cell], chosen[placed] = True, cell
            placed += 1
            if placed == chosen.shape[0]:
                break
    return placed


def finite(value: object) -> bool:
    return (is_int(value) or isinstance(value, (float, np.floating))) and np.isfinite(value)


def _replace_share(
    severity: float,
    weights: np.ndarray | None,
    p: np.ndarray,
    u: np.ndarray,
    free: np.ndarray,
    count: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Targets of which each, with probability `severity`, is drawn from `weights` over the free cells left
    (uniform when None, or when they hold no mass there) instead of the prior's placement. Draws: `count`
    uniforms, the prior's placement of the others, then the replaced ones' cells without replacement."""
    off = int((rng.random(count) < severity).sum())
    placed = place_targets(p, u, free, count - off, rng) if off < count else np.zeros((0, 2), np.int64)
    left = free.copy()
    left[placed[:, 0], placed[:, 1]] = False
    cells = np.flatnonzero(left.ravel())
    chance = None
    if weights is not None:
        chance = weights.ravel()[cells]
        chance = chance / chance.sum() if chance.sum() > 0 else None
    chosen = rng.choice(cells, size=off, replace=False, p=chance).astype(np.int64)
    return np.concatenate([placed, np.stack(np.divmod(chosen, free.shape[0]), axis=1)])


@dataclass(frozen=True)
class PriorTargets:
    """§4.1.4: targets placed from the prior itself (`place_targets`, the paper's two-stage law)."""

    kind: ClassVar[str] = "prior"

    def __call__(
        self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator
    ) -> np.ndarray:
        return place_targets(p, u, free, count, rng)

    def check(self, config: WorldConfig) -> None:
        pass

    @property
    def label(self) -> str:
        return ""

    @property
    def follows_prior(self) -> bool:
        """Targets placed by §4.1.4's law from the prior the agents hold (what the search bound assumes)."""
        return True


@dataclass(frozen=True)
class PriorError:
    """A family of prior error: `severity` 0 is the paper's placement, drawn exactly as `PriorTargets` draws it;
    above 0 the family's own law, `wrong`."""

    kind: ClassVar[str] = ""
    severity: float = 1.0

    def __call__(
        self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator
    ) -> np.ndarray:
        return place_targets(p, u, free, count, rng) if self.severity == 0 else self.wrong(p, u, free, count, rng)

    def wrong(self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
        raise NotImplementedError

    def check(self, config: WorldConfig) -> None:
        need(
            finite(self.severity) and 0 <= self.severity <= 1,
            "scenario.targets.severity",
            self.severity,
            "0 <= severity <= 1 (0: the paper's placement; 1: the family's most wrong prior)",
        )

    @property
    def label(self) -> str:
        return f"{self.kind}{self.severity:g}"

    @property
    def family(self) -> str:
        """The family's name in result rows (`Scenario.family`)."""
        return self.kind

    @property
    def follows_prior(self) -> bool:
        return self.severity == 0


@dataclass(frozen=True)
class OffPriorTargets(PriorError):
    """Targets off the prior: each of the j targets, independently with probability `severity`, lies uniformly on
    a free cell instead of following §4.1.4's law; the agents still start from the prior. Severity 1 places every
    target uniformly (the prior says nothing about where they are)."""

    kind: ClassVar[str] = "off_prior"

    def wrong(self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
        return _replace_share(self.severity, None, p, u, free, count, rng)


@dataclass(frozen=True)
class AdversarialTargets(PriorError):
    """Each target, with probability `severity`, placed from the prior turned upside down: the free cells ranked by
    p, the lowest given the highest cell's mass, the second lowest the second highest's, and so on (the same
    sharpness as the prior, pointing away from it). Severity 1: every target where the prior says least."""

    kind: ClassVar[str] = "adversarial"

    def wrong(self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
        values = p[free]
        mirrored = np.empty_like(values)
        mirrored[np.argsort(values, kind="stable")] = np.sort(values)[::-1]  # the lowest cell takes the highest mass
        upside_down = np.zeros_like(p)
        upside_down[free] = mirrored
        return _replace_share(self.severity, upside_down, p, u, free, count, rng)


@dataclass(frozen=True)
class ShiftedTargets(PriorError):
    """The truth is the prior moved: p and u translated by round(s · distance · n) cells along a direction θ drawn
    uniformly in [0, 2π) (one uniform), wrapping around the edges; the targets follow §4.1.4's law on the
    translated maps. `distance` is the largest shift as a fraction of the side n."""

    kind: ClassVar[str] = "shifted"
    distance: float = 0.25

    def shift(self, n: int, rng: np.random.Generator) -> tuple[int, int]:
        """(rows, cols) the truth is moved by, from one uniform of `rng`."""
        theta = 2 * np.pi * rng.random()
        reach = self.severity * self.distance * n
        return round(reach * math.sin(theta)), round(reach * math.cos(theta))

    def wrong(self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
        moved = self.shift(p.shape[0], rng)
        return place_targets(np.roll(p, moved, axis=(0, 1)), np.roll(u, moved, axis=(0, 1)), free, count, rng)

    def check(self, config: WorldConfig) -> None:
        super().check(config)
        need(
            finite(self.distance) and 0 < self.distance <= 1,
            "scenario.targets.distance",
            self.distance,
            "0 < distance <= 1 (the largest shift, as a fraction of the world's side)",
        )

    @property
    def label(self) -> str:
        return super().label + (f"d{self.distance:g}" if self.distance != 0.25 else "")


@dataclass(frozen=True)
class TemperedTargets(PriorError):
    """The truth is the prior sharpened or flattened: targets follow §4.1.4's law on p^a (renormalised over the
    free cells), a = 1 + severity · (power − 1). power 4 (sharper): the prior's modes hold more of the targets than
    it says; power 0 (flatter): at severity 1 the first stage is uniform and only u's second stage remains."""

    kind: ClassVar[str] = "tempered"
    power: float = 4.0

    def wrong(self, p: np.ndarray, u: np.ndarray, free: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
        if self.power == 1:
            return place_targets(p, u, free, count, rng)
        truth = power(np.where(free, p, 0.0), 1.0 + self.severity * (self.power - 1.0))  # libm.py: why not numpy's
        return place_targets(truth / truth.sum(), u, free, count, rng)

    def check(self, config: WorldConfig) -> None:
        super().check(config)
        need(
            finite(self.power) and 0 <= self.power <= 16,
            "scenario.targets.power",
            self.power,
            "0 <= power <= 16 (> 1: the truth sharper than the prior; < 1: flatter)",
        )

    @property
    def label(self) -> str:
        return f"{super().label}p{self.power:g}"

    @property
    def family(self) -> str:
        return "sharper" if self.power > 1 else "flatter" if self.power < 1 else "tempered"


PLACERS: Registry[type] = Registry(
    "scenario.targets.kind",
    (PriorTargets, OffPriorTargets, ShiftedTargets, TemperedTargets, AdversarialTargets),
    key="kind",
)


def prior_quality(p: np.ndarray, free: np.ndarray, targets: np.ndarray) -> float:
    """How well the prior p (n, n) points at the true `targets` (j, 2), MapScore-like, in [-1, 1]: for each target,
    the share of free cells the prior rates lower than the target's cell minus the share it rates higher, averaged
    over the targets. 0: no better than a uniform prior (or uniform targets on average); 1: every target on the
    prior's single best cell; -1: on its worst. NaN without targets."""
    if len(targets) == 0:
        return float("nan")
    values = np.sort(p[free])
    at = p[targets[:, 0], targets[:, 1]]
    lower = np.searchsorted(values, at, side="left")
    higher = len(values) - np.searchsorted(values, at, side="right")
    return float(np.mean((lower - higher) / len(values)))


def prior_qualities(state: WorldState, worlds: Sequence[int] | None = None) -> np.ndarray:
    """(len(worlds),) float64, every world's (K,) by default: `prior_quality` of each listed world of `state` as it
    stands (the prior p the agents started from, its free cells and its targets), read at an episode's start."""
    h = state.halo
    worlds = range(state.n_worlds) if worlds is None else worlds
    out = np.full(len(worlds), np.nan)
    for i, k in enumerate(worlds):
        inner = (k, slice(h, h + int(state.size[k])), slice(h, h + int(state.size[k])))
        targets = state.target_pos[k, : int(state.n_targets[k])]
        out[i] = prior_quality(state.p[inner], ~state.blocked[inner], targets)
    return out
