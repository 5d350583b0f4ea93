"""Validation: a policy's episodes on a fixed set of worlds, played as evaluation plays them.

World w of a validation set with seed s is the evaluation's map w of cell 0 under seed s: map seed s + w, episode
key (s, 0, w, 0) (searchrl/controllers/episodes.py). The policy acts through `PolicyController`, the evaluation's
inference path, with actions sampled from the episode's own stream (or argmax), so the same weights give the same
metrics at every validation (common random numbers: a curve's steps are changes of the weights, not of sampling
luck) and a validation's found fraction is what `python -m searchrl.evaluate` reports on the same worlds when its
`device=` is the training's (cpu for both by default). On another device the logits round otherwise and a sampled
action may flip (searchrl/policies/actor.py).

Validation acts with a copy of the training policy on the model's device (`policy_copy`), on every device alike: the
policy that trains on keeps its mode and weights, and torch's global generator, which training samples from, is
left where it was.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

from searchrl.controllers.base import RandomWalk
from searchrl.controllers.episodes import play_episodes
from searchrl.controllers.factory import policy_factory
from searchrl.policies.actor import Actor, policy_copy
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import PAPER, Scenario


def run_episodes(
    world_config: WorldConfig,
    n_worlds: int,
    seed: int,
    model: OnPolicyAlgorithm | None,
    deterministic: bool = False,
    scenario: Scenario = PAPER,
) -> dict[str, float]:
    """Mean episode metrics of `model`'s policy (or of a random walk, None) over the validation set of `n_worlds`
    worlds drawn from `seed` under `scenario` (module docstring)."""
    if model is None:
        factory = RandomWalk
    else:
        # Traced as evaluation's is (about 0.2 s), so both act alike to the last bit on the same device.
        factory = policy_factory(Actor(policy_copy(model), device=model.device), deterministic)

    keys = [(seed, 0, w, 0) for w in range(n_worlds)]
    metrics = play_episodes(factory, world_config, [seed + w for w in range(n_worlds)], keys, scenario)
    return {name: float(np.mean(values)) for name, values in metrics.items() if name != "prior_quality"}  # a world's
