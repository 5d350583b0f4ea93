"""The sensor footprint Γ of §3.1 and the move table of §3.2.2."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


def make_footprint(radius: int = 2) -> np.ndarray:
    """Γ[dy + r, dx + r] = exp(-(dx² + dy²) / 2) on the disc dx² + dy² <= r², 0 outside. Shape (2r+1, 2r+1).
    Python's math.exp, the C library's, not numpy's (searchrl/world/libm.py says why)."""
    d = range(-radius, radius + 1)
    return np.array(
        [[math.exp(-(dy * dy + dx * dx) / 2.0) if dy * dy + dx * dx <= radius**2 else 0.0 for dx in d] for dy in d]
    )


GAMMA: np.ndarray = make_footprint(2)  # (5, 5) float64; the paper prints it to 4 decimals

# The 13 non-zero cells of Γ as offsets from the centre, row-major (the kernels' footprint arguments).
_SUPPORT = np.argwhere(GAMMA > 0)
SUPPORT_DR: np.ndarray = (_SUPPORT[:, 0] - 2).astype(np.int64)  # (13,)
SUPPORT_DC: np.ndarray = (_SUPPORT[:, 1] - 2).astype(np.int64)  # (13,)
SUPPORT_G: np.ndarray = GAMMA[GAMMA > 0].astype(np.float64)  # (13,)


class Footprint(NamedTuple):
    """Γ's support as the compiled kernels take it: cell s of the footprint is offset (dr[s], dc[s]) from the agent
    and weighs g[s]."""

    dr: np.ndarray  # (13,) int64
    dc: np.ndarray  # (13,) int64
    g: np.ndarray  # (13,) float64


SUPPORT = Footprint(SUPPORT_DR, SUPPORT_DC, SUPPORT_G)


def team_sensing_rate(blocked: np.ndarray, n_agents: int) -> np.ndarray:
    """ρ = N·ΣΓ / free cells per world, (K,) float64 from blocked (K, S, S) bool: the footprint mass a team of N
    spread evenly puts on each free cell per step. Greedy's `age` and the world's `belief_age` scale it."""
    free = (~blocked).sum(axis=(1, 2))
    return n_agents * float(GAMMA.sum()) / np.maximum(free, 1)


# Moves as (d_row, d_col); row grows southwards, col eastwards. First 5 are the cardinal mode.
MOVES: np.ndarray = np.array(
    [(0, 0), (-1, 0), (0, 1), (1, 0), (0, -1), (-1, 1), (1, 1), (1, -1), (-1, -1)],
    dtype=np.int64,
)
ACTION_NAMES: tuple[str, ...] = ("stay", "N", "E", "S", "W", "NE", "SE", "SW", "NW")
