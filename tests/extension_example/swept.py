"""An observation part and the network that reads it: which cells any footprint has swept, pooled onto a grid."""

from __future__ import annotations

import numpy as np

from searchrl.envs.parts import register_part
from searchrl.policies.networks import WithGrid, register_network


@register_part
class Swept:
    key = "swept"
    privileged = False
    high = 1.0

    def __init__(self, grid: int = 16) -> None:
        self.grid = grid

    def shape(self, config) -> tuple[int, ...]:
        return (config.n_agents, 1, self.grid, self.grid)

    def fill(self, state, config, out: np.ndarray, worlds: np.ndarray) -> None:
        h, g = state.halo, self.grid
        for k in worlds:
            n = int(state.size[k])
            cells = state.swept[k, h : h + n, h : h + n].astype(np.float32)
            rows = np.arange(n) * g // n
            pooled = np.zeros((g, g), np.float32)
            np.add.at(pooled, (rows[:, None], rows[None, :]), cells)
            counts = np.bincount(rows, minlength=g).astype(np.float32)
            out[k, :, 0] = pooled / np.maximum(np.outer(counts, counts), 1)


@register_network("swept_cnn")
class SweptCNN(WithGrid):
    part = "swept"
    gated = False
