"""Information maps of §4.1.3: mixtures of bivariate Gaussians (eq. 6) normalised as in eq. 7 and 8."""

from __future__ import annotations

import numpy as np


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
    # exp(-quad / (2(1 - ρ²))) / (2π σx σy √(1 - ρ²)), worked in place in one (m, n_y, n_x) array: at n = 160 each
    # temporary is 13 MB. The same operations in the same order, so the same bits (a negated divisor is exact).
    density = dx[:, None, :] ** 2 + dy[:, :, None] ** 2
    density -= 2.0 * rho[:, None, None] * dx[:, None, :] * dy[:, :, None]
    np.divide(density, -(2.0 * one_minus)[:, None, None], out=density)
    np.exp(density, out=density)
    density /= (2.0 * np.pi * sx * sy * np.sqrt(one_minus))[:, None, None]
    return density


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
