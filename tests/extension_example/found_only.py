"""A reward: only what the team finds (`weight` x 10 per target credited), less the paper's step cost:
`reward=found_only reward.weight=2`."""

from __future__ import annotations

import numpy as np

from searchrl.envs.rewards import register_reward


@register_reward("found_only")
class FoundOnly:
    def __init__(self, weight: float = 1.0) -> None:
        self.weight = weight

    def __call__(self, config, result) -> np.ndarray:
        paid = self.weight * config.target_reward * result.targets_found + config.step_reward
        return paid.astype(np.float32)
