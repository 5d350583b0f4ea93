"""An obstacle law: a wall on every cell whose row and column are both multiples of `every`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from hydra.core.config_store import ConfigStore

from searchrl.world.scenario import register_part


@dataclass(frozen=True)
class Pillars:
    kind: ClassVar[str] = "pillars"
    every: int = 4

    def __call__(self, n: int, room: int, rng: np.random.Generator) -> np.ndarray:
        walls = np.zeros((n, n), bool)
        walls[self.every :: self.every, self.every :: self.every] = True
        return walls

    def check(self, config) -> None:
        if self.every < 2:
            raise ValueError(f"scenario.obstacles.every={self.every!r} is not allowed: >= 2")

    @property
    def label(self) -> str:
        return f"pillars{self.every}"


register_part("obstacles", Pillars)

# The scenario that uses it, `scenario=pillars`: a conf/scenario/ file's content, stored from here (no yaml needed).
ConfigStore.instance().store(
    group="scenario",
    name="pillars",
    node={"obstacles": {"kind": "pillars", "every": 4}, "prior": {"kind": "mixture"}, "targets": {"kind": "prior"}},
)
