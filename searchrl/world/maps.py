"""Information maps of §4.1.3: mixtures of bivariate Gaussians (eq. 6) normalised as in eq. 7 and 8."""

from __future__ import annotations

import numpy as np
from numba import njit

from searchrl.world.kernels import CACHE


def gaussian_components(
    n: int, m: int, variance_high: float, variance_low: float, rho_max: float, rng: np.random.Generator
) -> np.ndarray:
    """The m bivariate Gaussian densities of eq. 6, each evaluated at the cell centres of an n×n grid.

    Means are uniform over [0, n - 1]², each σ² uniform in [variance_low, variance_high), ρ uniform in
    (-rho_max, rho_max). Returns (m, n, n) float64 indexed [component, row = y, col = x].
    """
    mu = rng.uniform(0.0, n - 1.0, size=(m, 2))  # (m, 2) as (x, y)
    var = rng.uniform(variance_low, variance_high, size=(m, 2))  # (m, 2) σ_x², σ_y²
    rho = rng.uniform(-rho_max, rho_max, size=m)  # (m,)
    sx, sy = np.sqrt(var[:, 0]), np.sqrt(var[:, 1])
    coords = np.arange(n, dtype=np.float64)
    dx = (coords[None, :] - mu[:, 0:1]) / sx[:, None]  # (m, n) over x
    dy = (coords[None, :] - mu[:, 1:2]) / sy[:, None]  # (m, n) over y
    one_minus = 1.0 - rho**2
    # exp(-quad / (2(1 - ρ²))) / (2π σx σy √(1 - ρ²)) in one (m, n_y, n_x) array: the exponent in one compiled
    # pass, then numpy's exp and the normalisation in place. The same operations in the same order as numpy's
    # broadcasts, so the same bits (a negated divisor is exact; tests/test_generation.py holds them).
    density = np.empty((m, n, n), np.float64)
    _exponents(dx, dy, 2.0 * rho, -(2.0 * one_minus), density)
    np.exp(density, out=density)
    density /= (2.0 * np.pi * sx * sy * np.sqrt(one_minus))[:, None, None]
    return density


@njit(cache=CACHE)
def _exponents(dx, dy, two_rho, divisor, out):
    """out[i, y, x] = (dx[i, x]² + dy[i, y]² − (2ρ_i · dx[i, x]) · dy[i, y]) / divisor[i], eq. 6's exponent for
    dx, dy (m, n) the standardised distances, two_rho and divisor (m,) and out (m, n, n) float64."""
    for i in range(out.shape[0]):
        for y in range(out.shape[1]):
            dy2 = dy[i, y] * dy[i, y]
            for x in range(out.shape[2]):
                quad = dx[i, x] * dx[i, x] + dy2
                out[i, y, x] = (quad - two_rho[i] * dx[i, x] * dy[i, y]) / divisor[i]


def gaussian_mixture(
    n: int, m: int, variance_high: float, variance_low: float, rho_max: float, rng: np.random.Generator
) -> np.ndarray:
    """Sum of the m densities of `gaussian_components` (eq. 6): (n, n) float64 indexed [row = y, col = x]."""
    return gaussian_components(n, m, variance_high, variance_low, rho_max, rng).sum(axis=0)


def probability_map(mixture: np.ndarray, eta: float) -> np.ndarray:
    """Eq. 7: (1 - η)·F/ΣF plus η spread evenly, so p sums to 1 and no cell is below η / n²."""
    total = mixture.sum()
    return ((1.0 - eta) * mixture + eta * total / mixture.size) / total


def uncertainty_map(mixture: np.ndarray) -> np.ndarray:
    """Eq. 8: F / ΣF, no baseline."""
    return mixture / mixture.sum()
