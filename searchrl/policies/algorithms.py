"""The SB3 algorithms a run may use, by config name, with the policy class each is built with (RecurrentPPO's:
sb3-contrib's MultiInputLstmPolicy with its LSTM run over whole sequences, searchrl/policies/recurrent.py)."""

from __future__ import annotations

from sb3_contrib import RecurrentPPO
from stable_baselines3 import A2C
from stable_baselines3.common.base_class import BaseAlgorithm

from searchrl.policies.recurrent import SequenceLstmPolicy

ALGORITHMS: dict[str, tuple[type[BaseAlgorithm], str | type]] = {
    "recurrent_ppo": (RecurrentPPO, SequenceLstmPolicy),
    "a2c": (A2C, "MultiInputPolicy"),
}
