"""Information maps of §4.1.3: mixtures of bivariate Gaussians (eq. 6) normalised as in eq. 7 and 8."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from searchrl.world.kernels import CACHE
from searchrl.world.parallel import chunk_count, chunk_span, world_threads
from searchrl.world.sums import numpy_sum


@dataclass(frozen=True)
class Gaussians:
    """The m bivariate Gaussians of eq. 6: means mu (m, 2) as (x, y), variances var (m, 2) as (σ_x², σ_y²) and
    correlations rho (m,), float64."""

    mu: np.ndarray
    var: np.ndarray
    rho: np.ndarray

    @staticmethod
    def draw(
        n: int, m: int, variance_high: float, variance_low: float, rho_max: float, rng: np.random.Generator
    ) -> Gaussians:
        """Means uniform over [0, n - 1]², each σ² uniform in [variance_low, variance_high), ρ uniform in
        (-rho_max, rho_max), drawn in that order."""
        mu = rng.uniform(0.0, n - 1.0, size=(m, 2))
        var = rng.uniform(variance_low, variance_high, size=(m, 2))
        rho = rng.uniform(-rho_max, rho_max, size=m)
        return Gaussians(mu, var, rho)

    def __add__(self, other: Gaussians) -> Gaussians:
        """Both sets, self's first: their densities come from one `densities` call."""
        return Gaussians(
            np.concatenate((self.mu, other.mu)),
            np.concatenate((self.var, other.var)),
            np.concatenate((self.rho, other.rho)),
        )

    def densities(self, n: int) -> np.ndarray:
        """Each Gaussian's density at the cell centres of an n×n grid: (m, n, n) float64 [component, row = y,
        col = x], exp(-quad / (2(1 - ρ²))) / (2π σx σy √(1 - ρ²)).

        One compiled pass, its m·n rows shared among the world's numba threads (searchrl/world/parallel.py). It
        works the same operations in the same order as numpy's broadcasts of the formula, and its exp is the C
        library's, the one numpy's float64 exp calls on CPUs without AVX-512: the same bits at any thread count
        (tests/test_generation.py holds them)."""
        out = np.empty((self.rho.shape[0], n, n), np.float64)
        _densities(self.mu, self.var, self.rho, out, world_threads())
        return out


def gaussian_components(
    n: int, m: int, variance_high: float, variance_low: float, rho_max: float, rng: np.random.Generator
) -> np.ndarray:
    """The m densities of eq. 6 drawn as `Gaussians.draw` says, at the cells of an n×n grid: (m, n, n) float64."""
    return Gaussians.draw(n, m, variance_high, variance_low, rho_max, rng).densities(n)


@njit(cache=CACHE, parallel=True)
def _densities(mu, var, rho, out, threads):
    """out (m, n, n) float64 = eq. 6 for the Gaussians mu, var (m, 2) and rho (m,): the standardised distances
    (m, n) in this thread, then the rows (i, y) cut into up to `threads` chunks; one chunk runs in the calling
    thread (no parallel region)."""
    m, n = out.shape[0], out.shape[1]
    dx, dy = np.empty((m, n)), np.empty((m, n))
    two_rho, divisor, norm = np.empty(m), np.empty(m), np.empty(m)
    for i in range(m):
        sx, sy, one_minus = math.sqrt(var[i, 0]), math.sqrt(var[i, 1]), 1.0 - rho[i] * rho[i]
        for c in range(n):
            dx[i, c] = (c - mu[i, 0]) / sx
            dy[i, c] = (c - mu[i, 1]) / sy
        two_rho[i], divisor[i] = 2.0 * rho[i], -(2.0 * one_minus)  # a negated divisor is exact
        norm[i] = 2.0 * np.pi * sx * sy * math.sqrt(one_minus)
    rows = m * n
    n_chunks = chunk_count(rows, rows, threads)
    if n_chunks == 1:
        _density_rows(dx, dy, two_rho, divisor, norm, out, np.int64(0), rows)
        return
    for chunk in prange(n_chunks):
        first, stop = chunk_span(chunk, n_chunks, 0, rows)
        _density_rows(dx, dy, two_rho, divisor, norm, out, first, stop)


@njit(cache=CACHE)
def _density_rows(dx, dy, two_rho, divisor, norm, out, first, stop):
    """Rows first..stop-1 of out (row = i · n + y): exp((dx² + dy² − (2ρ · dx) · dy) / divisor) / norm."""
    n = out.shape[1]
    for row in range(first, stop):
        i, y = row // n, row % n
        dyi, two_rho_i, divisor_i, norm_i = dy[i, y], two_rho[i], divisor[i], norm[i]
        dy2 = dyi * dyi
        for x in range(out.shape[2]):
            quad = dx[i, x] * dx[i, x] + dy2
            out[i, y, x] = math.exp((quad - two_rho_i * dx[i, x] * dyi) / divisor_i) / norm_i


def mixture_maps(densities: np.ndarray, m: int, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """(p, u), (n, n) float64 each: eq. 7 of the mixture of the first m of `densities` (M, n, n) float64 and eq. 8
    of the mixture of the rest, in one compiled pass whose grid rows are shared among the world's threads. The
    same bits as `probability_map(densities[:m].sum(axis=0), eta)` and `uncertainty_map(densities[m:].sum(axis=0))`
    (numpy adds the components in order, cell by cell, and sums a map pairwise: `sums.numpy_sum`)."""
    n = densities.shape[1]
    p, u = np.empty((n, n), np.float64), np.empty((n, n), np.float64)
    _mixture_maps(densities, m, eta, p, u, world_threads())
    return p, u


@njit(cache=CACHE, parallel=True)
def _mixture_maps(densities, m, eta, p, u, threads):
    """p and u (n, n) = `mixture_maps`: the mixtures row by row, their totals in this thread, then eq. 7 and 8 row
    by row; the rows cut into up to `threads` chunks, one chunk run in the calling thread (no parallel region)."""
    n = p.shape[0]
    n_chunks = chunk_count(n, n, threads)
    if n_chunks == 1:
        _mixture_rows(densities, m, p, u, np.int64(0), n)
    else:
        for chunk in prange(n_chunks):
            first, stop = chunk_span(chunk, n_chunks, 0, n)
            _mixture_rows(densities, m, p, u, first, stop)
    p_total, u_total = numpy_sum(p.ravel()), numpy_sum(u.ravel())
    floor = eta * p_total / p.size  # eq. 7's η spread evenly, as `probability_map` computes it
    if n_chunks == 1:
        _normalised_rows(p, u, 1.0 - eta, floor, p_total, u_total, np.int64(0), n)
        return
    for chunk in prange(n_chunks):
        first, stop = chunk_span(chunk, n_chunks, 0, n)
        _normalised_rows(p, u, 1.0 - eta, floor, p_total, u_total, first, stop)


@njit(cache=CACHE)
def _mixture_rows(densities, m, p, u, first, stop):
    """Rows first..stop-1 of p = Σ_{i<m} densities[i] and u = Σ_{i>=m} densities[i], each added in order of i."""
    for y in range(first, stop):
        _add_components(densities, np.int64(0), m, p, y)
        _add_components(densities, m, densities.shape[0], u, y)


@njit(cache=CACHE)
def _add_components(densities, first, stop, mixture, y):
    """Row y of mixture = densities[first] + ... + densities[stop - 1], component by component along the row:
    contiguous, and in numpy's order."""
    for x in range(mixture.shape[1]):
        mixture[y, x] = densities[first, y, x]
    for i in range(first + 1, stop):
        for x in range(mixture.shape[1]):
            mixture[y, x] += densities[i, y, x]


@njit(cache=CACHE)
def _normalised_rows(p, u, weight, floor, p_total, u_total, first, stop):
    """Rows first..stop-1: p = (weight · p + floor) / p_total (eq. 7) and u = u / u_total (eq. 8), in place."""
    for y in range(first, stop):
        for x in range(p.shape[1]):
            p[y, x] = (weight * p[y, x] + floor) / p_total
            u[y, x] = u[y, x] / u_total


def probability_map(mixture: np.ndarray, eta: float) -> np.ndarray:
    """Eq. 7: (1 - η)·F/ΣF plus η spread evenly, so p sums to 1 and no cell is below η / n²."""
    total = mixture.sum()
    return ((1.0 - eta) * mixture + eta * total / mixture.size) / total


def uncertainty_map(mixture: np.ndarray) -> np.ndarray:
    """Eq. 8: F / ΣF, no baseline."""
    return mixture / mixture.sum()
