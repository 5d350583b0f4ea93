"""An observation part and the network that reads it: which cells any footprint has swept, pooled onto a grid.
Each takes a setting (its constructor's typed keyword argument): `network=swept_cnn network.width=24
network.scale=0.5`."""

from __future__ import annotations

import numpy as np
from torch import nn

from searchrl.envs.parts import register_part
from searchrl.policies.networks import WithGrid, grid_encoder, register_critic, register_network


@register_part
class Swept:
    key = "swept"
    privileged = False

    def __init__(self, grid: int = 16, scale: float = 1.0) -> None:
        self.grid, self.scale, self.high = grid, scale, scale  # a swept cell reads `scale`

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
            out[k, :, 0] = self.scale * pooled / np.maximum(np.outer(counts, counts), 1)


@register_network("swept_cnn")
class SweptCNN(WithGrid):
    part = "swept"
    gated = False

    def __init__(self, observation_space, width: int = 32, **sizes) -> None:
        super().__init__(observation_space, **sizes)
        channels, grid, _ = observation_space[self.part].shape
        self.grid = nn.Sequential(grid_encoder(channels, grid, width), nn.Linear(width, self.features_dim))


@register_critic("swept_critic")
class SweptCritic(WithGrid):
    part = "swept"
    gated = False
