"""A heuristic: every agent moves east (action 2) until `margin` cells before the east edge, then random moves:
`controller=eastward controller.margin=2`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.registry import register
from searchrl.world.streams import random_source


@dataclass
class EastwardConfig(ControllerConfig):
    name: str = "eastward"
    margin: int = 0  # cells before the east edge where an agent turns to random moves


class Eastward:
    def __init__(self, config, margin: int = 0, seed=0) -> None:
        self.config, self.margin, self.rng = config, margin, random_source(seed)

    def reset(self, state, mask) -> None:
        pass

    def act(self, state, maps, vector, active=None) -> np.ndarray:
        moves = self.rng.integers(1, self.config.n_actions, size=(state.n_worlds, state.n_agents))
        at_edge = state.pos[:, :, 1] >= state.size[:, None] - 1 - self.margin
        return np.where(at_edge, moves, 2)


register("eastward", Eastward, EastwardConfig)
