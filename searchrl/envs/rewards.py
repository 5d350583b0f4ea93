"""Rewards by name: what a training env pays each agent for a step, from what the step produced.

A reward is a callable `(config, result) -> (K, N) float32` of the world's `StepResult` (searchrl/world/step.py: the
paper's reward and its parts per agent: targets credited, information collected, communication gain, blocked
moves), injected into the VecEnv (`SearchVecEnv(reward=...)`), as Jumanji injects a RewardFn. It registers here
(`register_reward`) and a run picks it with `reward=<name>`. `paper`, the default, pays the world's own reward
(Table 1 + eq. 5 + eq. 17). Episode metrics (R, found fraction) stay the world's whatever the reward.
"""

from __future__ import annotations

from collections.abc import Callable
from difflib import get_close_matches
from typing import Protocol

import numpy as np

from searchrl.world.config import WorldConfig
from searchrl.world.step import StepResult


class RewardFn(Protocol):
    def __call__(self, config: WorldConfig, result: StepResult) -> np.ndarray: ...


REWARDS: dict[str, Callable[[], RewardFn]] = {}


def register_reward(name: str) -> Callable[[Callable[[], RewardFn]], Callable[[], RewardFn]]:
    """Decorator: register a reward class (built with no arguments) as `reward=<name>`."""

    def add(cls: Callable[[], RewardFn]) -> Callable[[], RewardFn]:
        if REWARDS.get(name, cls) is not cls:
            raise ValueError(f"reward {name!r} is registered already ({REWARDS[name]!r})")
        REWARDS[name] = cls
        return cls

    return add


@register_reward("paper")
class PaperReward:
    """The world's own reward: Table 1's step, collision and target terms, eq. 5's information, eq. 17's sharing."""

    def __call__(self, config: WorldConfig, result: StepResult) -> np.ndarray:
        return result.reward


def make_reward(name: str) -> RewardFn:
    """The reward registered as `name`; ValueError naming the nearest registered name."""
    if name not in REWARDS:
        near = get_close_matches(name, REWARDS, n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise ValueError(f"reward={name!r} is not registered{hint}: one of {sorted(REWARDS)}")
    return REWARDS[name]()
