"""Observation and action spaces shared by every env layer."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from searchrl.world.coarse import ObservationPart
from searchrl.world.config import WorldConfig
from searchrl.world.observe import VECTOR_SIZE, n_channels


def observation_space(config: WorldConfig, parts: Sequence[ObservationPart] = ()) -> spaces.Dict:
    """{"map": (C, fov, fov), "vector": (3,)} float32 in [0, 1], C = 5 or 6 (`n_channels`): beliefs never exceed
    the prior, whose peak is scaled to 1; freshness is a factor in (0, 1]; positions are divided by n; remaining
    targets by their count. Each of `parts` adds its key, its shape per agent, in [0, part.high]."""
    return spaces.Dict(
        {
            "map": spaces.Box(0.0, 1.0, (n_channels(config), config.fov, config.fov), np.float32),
            "vector": spaces.Box(0.0, 1.0, (VECTOR_SIZE,), np.float32),
            **{p.key: spaces.Box(0.0, p.high, p.shape(config)[1:], np.float32) for p in parts},
        }
    )


def action_space(config: WorldConfig) -> spaces.Discrete:
    """Stay, N, E, S, W (and NE, SE, SW, NW in diagonal mode)."""
    return spaces.Discrete(config.n_actions)
