"""numpy's float64 sums in compiled code, so a tally or a map normalised in a kernel has the bits numpy gives."""

from __future__ import annotations

import numpy as np
from numba import njit

from searchrl.world.kernels import CACHE


@njit(cache=CACHE)
def numpy_sum(values):
    """values.sum() as numpy adds a contiguous float64 row (N,), so a tally made here equals numpy's bit for bit
    (tests/test_engine.py checks every length up to 1,100; a contiguous (n, n) map's `.sum()` is this sum of its n²
    values, tests/test_generation.py): numpy sums a row of up to 128 in eight partial sums (`_block_sum`) and a
    longer one as the sum of its halves, the first a multiple of 8 long. Those halves are walked with a stack, not
    by recursion: numba cannot load a cached recursive function (numba issue #6061: a segfault)."""
    count = values.shape[0]
    if count <= 128:
        return _block_sum(values, np.int64(0), count)
    starts, counts = np.empty(64, np.int64), np.empty(64, np.int64)  # a frame per half being summed
    stage, left = np.zeros(64, np.int64), np.empty(64, np.float64)  # 0: to do, 1: first half, 2: second half
    top, total = 0, 0.0
    starts[0], counts[0] = 0, count
    while top >= 0:
        n = counts[top]
        half = n // 2 - (n // 2) % 8
        if n <= 128:  # a block: its sum goes back to the frame below
            total = _block_sum(values, starts[top], n)
            top -= 1
        elif stage[top] == 0:
            stage[top] = 1
            top += 1
            starts[top], counts[top], stage[top] = starts[top - 1], half, 0
        elif stage[top] == 1:
            left[top], stage[top] = total, 2
            top += 1
            starts[top], counts[top], stage[top] = starts[top - 1] + half, n - half, 0
        else:
            total = left[top] + total
            top -= 1
    return total


@njit(cache=CACHE)
def _block_sum(values, first, count):
    """numpy's sum of a row of at most 128: in order below 8, else eight partial sums combined pairwise, then the
    remainder in order."""
    if count < 8:
        total = 0.0
        for i in range(first, first + count):
            total += values[i]
        return total
    r0, r1, r2, r3 = values[first], values[first + 1], values[first + 2], values[first + 3]
    r4, r5, r6, r7 = values[first + 4], values[first + 5], values[first + 6], values[first + 7]
    whole = first + count - count % 8
    for i in range(first + 8, whole, 8):
        r0 += values[i]
        r1 += values[i + 1]
        r2 += values[i + 2]
        r3 += values[i + 3]
        r4 += values[i + 4]
        r5 += values[i + 5]
        r6 += values[i + 6]
        r7 += values[i + 7]
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for j in range(whole, first + count):
        total += values[j]
    return total
