# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A team reward and an own reward (an extension module)
#
# Two research rewards, registered through the library's extension point (`extensions=[analysis.team_reward]`).
#
# `team_found`: every agent of a world is paid the number of targets its whole team found this step, and nothing
# else. Summed over an episode it is the team's found count, the quantity the evaluation scores (found fraction =
# found / targets), so with `algo.gamma=1` PPO's objective is the metric itself. This is MAPPO's shared team reward
# (Yu et al., "The Surprising Effectiveness of PPO in Cooperative Multi-Agent Games"): it removes the paper's
# per-agent credit (an agent is paid for the targets it finds, and for information, which the team's score does not
# count), at the price of a noisier signal per agent, which a critic of the true state (`critic=true_state`, which
# sees every agent, the targets left and the time left) is there to absorb.

# %%
from __future__ import annotations

import numpy as np

from searchrl.envs.rewards import register_reward
from searchrl.world.config import WorldConfig
from searchrl.world.step import StepResult

# %% [markdown]
# Each step's reward, per agent: its world's finds, the same for the whole team.


# %%
@register_reward("team_found")
class TeamFound:
    """(K, N) float32: each agent gets its world's targets found this step (the sum over the team)."""

    def __call__(self, config: WorldConfig, result: StepResult) -> np.ndarray:
        found = result.targets_found.sum(axis=1, keepdims=True)  # (K, 1)
        return np.repeat(found, result.targets_found.shape[1], axis=1).astype(np.float32)


# %% [markdown]
# `own_found`: each agent is paid the targets credited to it this step, and nothing else (no information, sharing,
# step or collision terms). Summed over the team and an episode it is the same found count, so with `algo.gamma=1`
# the team's objective is still the metric, while each agent's return is its own finds: the per-agent credit that
# `team_found` gives up, without the paper's terms that the score does not count.


# %%
@register_reward("own_found")
class OwnFound:
    """(K, N) float32: the targets credited to each agent this step."""

    def __call__(self, config: WorldConfig, result: StepResult) -> np.ndarray:
        return result.targets_found.astype(np.float32)
