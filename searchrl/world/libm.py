"""Elementwise log and power through the C library's scalar functions, so a seed draws the same worlds on every
x86-64 CPU.

numpy dispatches some float64 ufuncs to code written for the CPU's vector unit: on a CPU with AVX-512, `np.exp`,
`np.log` and `np.power` run their own AVX-512 routines, whose results differ from the C library's in the last bit
for a few inputs in a thousand. The world's maps, the prior-error truths, the heuristics' weights and the search
bound therefore never call those ufuncs: compiled code (numba lowers `math.log` and `**` to one scalar call of the
C library per element; it never vectorises a call to them) or Python's `math` module (the same functions) computes
them instead. tests/test_cpu_independence.py holds every module of the world to it and checks that the worlds do not
change when numpy's vector code is switched off.

Left to the C library: glibc chooses its exp/log/pow/sin/cos variant by CPU too (FMA or SSE2), which agree to the
last bit except in rare roundings; every x86-64 CPU since 2013 takes the FMA variant.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from searchrl.world.kernels import CACHE


@njit(cache=CACHE)
def log(x: np.ndarray) -> np.ndarray:
    """math.log of each element of x (any shape, float64): a new array of x's shape."""
    out = np.empty(x.shape, np.float64)
    flat, values = out.reshape(-1), np.ascontiguousarray(x).reshape(-1)
    for i in range(values.size):
        flat[i] = math.log(values[i])
    return out


@njit(cache=CACHE)
def power(x: np.ndarray, exponent: float) -> np.ndarray:
    """x[i] ** exponent for each element of x (any shape, float64), the C library's pow: a new array of x's shape."""
    out = np.empty(x.shape, np.float64)
    flat, values = out.reshape(-1), np.ascontiguousarray(x).reshape(-1)
    for i in range(values.size):
        flat[i] = values[i] ** exponent
    return out
