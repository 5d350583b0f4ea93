"""The SB3 algorithms a run may use, by config name, with the policy class each is built with."""

from __future__ import annotations

from sb3_contrib import RecurrentPPO
from stable_baselines3 import A2C
from stable_baselines3.common.base_class import BaseAlgorithm

ALGORITHMS: dict[str, tuple[type[BaseAlgorithm], str]] = {
    "recurrent_ppo": (RecurrentPPO, "MultiInputLstmPolicy"),
    "a2c": (A2C, "MultiInputPolicy"),
}
