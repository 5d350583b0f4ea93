"""Rewards by name: what a training env pays each agent for a step, from what the step produced.

A reward is a callable `(config, result) -> (K, N) float32` of the world's `StepResult` (searchrl/world/step.py: the
paper's reward and its parts per agent: targets credited, information collected, communication gain, blocked
moves), injected into the VecEnv (`SearchVecEnv(reward=...)`), as Jumanji injects a RewardFn. It registers here
(`register_reward`) and a run picks it with `reward=<name>`, its settings with `reward.<setting>=` (its constructor's
typed keyword arguments: searchrl/registry.py). `paper`, the default, pays the world's own reward (Table 1 + eq. 5 +
eq. 17). Episode metrics (R, found fraction) stay the world's whatever the reward.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from searchrl.registry import Registry, settings_of
from searchrl.world.config import WorldConfig
from searchrl.world.step import StepResult


class RewardFn(Protocol):
    def __call__(self, config: WorldConfig, result: StepResult) -> np.ndarray: ...


REWARDS: Registry[Callable[[], RewardFn]] = Registry("reward")


@dataclass
class RewardConfig:
    """A run's `reward` node: the reward by name; a registered reward's settings extend it (`reward_schema`)."""

    name: str = "paper"  # what the env pays per step; paper: the world's


def reward_schema(name: str) -> type[RewardConfig]:
    """RewardConfig extended by the settings of reward `name`."""
    return REWARDS.schema(name, RewardConfig, "name")


def register_reward(name: str) -> Callable[[Callable[[], RewardFn]], Callable[[], RewardFn]]:
    """Decorator: register a reward class (built with its settings as keyword arguments) as `reward=<name>`."""
    return REWARDS.register(name)


@register_reward("paper")
class PaperReward:
    """The world's own reward: Table 1's step, collision and target terms, eq. 5's information, eq. 17's sharing."""

    def __call__(self, config: WorldConfig, result: StepResult) -> np.ndarray:
        return result.reward


def make_reward(node: RewardConfig) -> RewardFn:
    """The reward of a run's `reward` node (its name and settings, typed by `reward_schema`); ConfigError naming
    an unregistered name."""
    cls = REWARDS.lookup(node.name)
    return cls(**{f.name: getattr(node, f.name) for f in dataclasses.fields(settings_of(cls)) if hasattr(node, f.name)})
