"""The prior the agents start from and the truth the targets come from (§4.1.3), as a scenario part.

A prior part is called as `prior(config, n, m, rng) -> PriorDraw`: the agents' maps p (eq. 7) and u (eq. 8), and the
truth's, from which the targets are placed (searchrl/world/truth.py). In the paper the truth is the prior itself;
the families below make the prior the agents hold differ from it, each with a severity s in [0, 1] whose 0 is the
paper's draw bit for bit (nothing more drawn from `rng`):

- `MixturePrior` (mixture, the paper's): p and u mixtures of m Gaussians, p's variances drawn below
  `variance_scale` · n (None: the world's `prob_variance_scale`, 10; 1 gives sharp priors, the second axis of the
  prior-error suite: a broad prior is worth little whether right or wrong);
- `MisweightedPrior` (misweighted): the truth is the same m Gaussians with weights (1 − s) + s · m · w, w drawn from
  a flat Dirichlet: the agents hold equal weights while some modes hold most of the targets and others almost none;
- `UninformedPrior` (uninformed): the agents hold (1 − s) · p + s · uniform, the truth keeps p: at s = 1 the
  agents' probability map says nothing of where the targets are.

Obstacles come after the prior in a reset: every map is renormalised over the free cells (searchrl/world/reset.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from searchrl.registry import Registry
from searchrl.world.config import WorldConfig, need
from searchrl.world.maps import Gaussians, mixture_maps, probability_map
from searchrl.world.truth import finite


@dataclass(frozen=True)
class PriorDraw:
    """The maps of one world, each (n, n) float64 summing to 1: what the agents start from (p, u) and what the
    targets are placed from (truth_p, truth_u; §4.1.4's two stages). When the prior is right they are p and u."""

    p: np.ndarray
    u: np.ndarray
    truth_p: np.ndarray
    truth_u: np.ndarray


@dataclass(frozen=True)
class MixturePrior:
    """§4.1.3: p from m Gaussians with σ² in [variance_floor, variance_scale · n) (None: the world's
    prob_variance_scale), u from m more with σ² below unc_variance_scale · n; the truth is the prior."""

    kind: ClassVar[str] = "mixture"
    variance_scale: float | None = None

    def components(
        self, config: WorldConfig, n: int, m: int, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p's m densities (m, n, n), p and u (n, n)), drawn in the paper's order: p's Gaussians, then u's."""
        scale = config.prob_variance_scale if self.variance_scale is None else self.variance_scale
        p_gaussians = Gaussians.draw(n, m, scale * n, config.variance_floor, config.rho_max, rng)
        u_gaussians = Gaussians.draw(n, m, config.unc_variance_scale * n, config.variance_floor, config.rho_max, rng)
        both = (p_gaussians + u_gaussians).densities(n)  # nothing more is drawn: both maps in compiled calls
        return (both[:m], *mixture_maps(both, m, config.eta))

    def __call__(self, config: WorldConfig, n: int, m: int, rng: np.random.Generator) -> PriorDraw:
        densities, p, u = self.components(config, n, m, rng)
        return self.truth(config, p, u, densities, rng)

    def truth(
        self, config: WorldConfig, p: np.ndarray, u: np.ndarray, densities: np.ndarray, rng: np.random.Generator
    ) -> PriorDraw:
        """The agents' maps and the truth's from the prior's own draw; the paper's: the truth is the prior."""
        return PriorDraw(p, u, p, u)

    def check(self, config: WorldConfig) -> None:
        if self.variance_scale is not None:
            need(
                finite(self.variance_scale) and 0 < self.variance_scale <= 1e6,
                "scenario.prior.variance_scale",
                self.variance_scale,
                "null (the world's prob_variance_scale) or 0 < scale <= 1e6",
            )
            need(
                config.variance_floor < self.variance_scale * config.world_size[0],
                "scenario.prior.variance_scale",
                self.variance_scale,
                f"scale · smallest n must exceed variance_floor={config.variance_floor}",
            )

    @property
    def label(self) -> str:
        return "" if self.variance_scale is None else f"var{self.variance_scale:g}"

    @property
    def truth_is_prior(self) -> bool:
        """The targets' maps are the agents' (what the search bound assumes)."""
        return True


@dataclass(frozen=True)
class PriorErrorMaps(MixturePrior):
    """A family of prior error in the maps: `severity` 0 is the paper's draw (nothing more drawn), above 0 the
    family's own `wrong` truth or agents' prior."""

    kind: ClassVar[str] = ""
    severity: float = 1.0

    def truth(
        self, config: WorldConfig, p: np.ndarray, u: np.ndarray, densities: np.ndarray, rng: np.random.Generator
    ) -> PriorDraw:
        return PriorDraw(p, u, p, u) if self.severity == 0 else self.wrong(config, p, u, densities, rng)

    def wrong(
        self, config: WorldConfig, p: np.ndarray, u: np.ndarray, densities: np.ndarray, rng: np.random.Generator
    ) -> PriorDraw:
        raise NotImplementedError

    def check(self, config: WorldConfig) -> None:
        super().check(config)
        need(
            finite(self.severity) and 0 <= self.severity <= 1,
            "scenario.prior.severity",
            self.severity,
            "0 <= severity <= 1 (0: the paper's prior; 1: the family's most wrong)",
        )

    @property
    def label(self) -> str:
        return "+".join(part for part in (super().label, f"{self.kind}{self.severity:g}") if part)

    @property
    def family(self) -> str:
        """The family's name in result rows (`Scenario.family`)."""
        return self.kind

    @property
    def truth_is_prior(self) -> bool:
        return self.severity == 0


@dataclass(frozen=True)
class MisweightedPrior(PriorErrorMaps):
    """The prior's modes mis-weighted: the truth is Σ w_i G_i (eq. 7's η kept) with w = (1 − s) + s · m · d, d drawn
    from a flat Dirichlet over the m Gaussians (m gamma draws), while the agents hold equal weights."""

    kind: ClassVar[str] = "misweighted"

    def wrong(
        self, config: WorldConfig, p: np.ndarray, u: np.ndarray, densities: np.ndarray, rng: np.random.Generator
    ) -> PriorDraw:
        m = densities.shape[0]
        weights = (1.0 - self.severity) + self.severity * m * rng.dirichlet(np.ones(m))
        return PriorDraw(p, u, probability_map(np.tensordot(weights, densities, axes=1), config.eta), u)


@dataclass(frozen=True)
class UninformedPrior(PriorErrorMaps):
    """The agents know less than the truth: they hold (1 − s) · p + s / n² while the targets follow p and u. At
    s = 1 their probability map is flat (no information where the targets are); nothing more is drawn. Their u
    stays the truth's: §4.1.4 keeps a target with probability 1 − u / max u, which a flat u would make 0 on every
    cell, so u cannot say "no information" (it only says where targets are rarer)."""

    kind: ClassVar[str] = "uninformed"

    def wrong(
        self, config: WorldConfig, p: np.ndarray, u: np.ndarray, densities: np.ndarray, rng: np.random.Generator
    ) -> PriorDraw:
        return PriorDraw((1.0 - self.severity) * p + self.severity / p.size, u, p, u)


PRIORS: Registry[type] = Registry("scenario.prior.kind", (MixturePrior, MisweightedPrior, UninformedPrior), key="kind")
