"""A reward: only what the team finds (10 per target credited), less the paper's step cost."""

from __future__ import annotations

import numpy as np

from searchrl.envs.rewards import register_reward


@register_reward("found_only")
class FoundOnly:
    def __call__(self, config, result) -> np.ndarray:
        return (config.target_reward * result.targets_found + config.step_reward).astype(np.float32)
