"""TeamMixVecEnv: groups of worlds with different N as one VecEnv; each group behaves exactly as on its own."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecMonitor

from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.world.config import WorldConfig

CONFIG = WorldConfig(world_size=(10, 16), n_targets=(2, 4), n_agents=2, max_steps=6)
BIG = replace(CONFIG, n_agents=5)


def _groups(seed: int = 0) -> list[SearchVecEnv]:
    return [SearchVecEnv(CONFIG, 3, seed=seed), SearchVecEnv(BIG, 2, seed=seed + 1)]


def test_slots_are_the_groups_concatenated_and_match_each_group_alone():
    mix, alone = TeamMixVecEnv(_groups()), _groups()
    assert mix.num_envs == 3 * 2 + 2 * 5
    obs = mix.reset()
    parts = [env.reset() for env in alone]
    assert np.array_equal(obs["map"], np.concatenate([p["map"] for p in parts]))
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(14):  # past two episode ends (max_steps = 6)
        actions = rng.integers(0, 5, size=mix.num_envs)
        obs, rewards, dones, infos = mix.step(actions)
        split = [env.step(a) for env, a in zip(alone, np.split(actions, [6]), strict=True)]
        assert np.array_equal(obs["vector"], np.concatenate([s[0]["vector"] for s in split]))
        assert np.array_equal(rewards, np.concatenate([s[1] for s in split]))
        assert np.array_equal(dones, np.concatenate([s[2] for s in split]))
        assert [sorted(i) for i in infos] == [sorted(i) for s in split for i in s[3]]
        # team metrics once per finished world, on its first slot: 0, 2, 4 (N = 2), then 6, 11 (N = 5)
        first_slots = [0, 2, 4, 6, 11]
        reported = [s for s, info in enumerate(infos) if "team_metrics" in info]
        assert reported == [s for s in first_slots if dones[s]]
        ends += len(reported)
    assert ends >= 2 * 5  # every world ends at least every 6 steps


def test_seed_seeds_group_j_with_seed_plus_j():
    mix = TeamMixVecEnv(_groups(seed=100))
    mix.seed(7)
    obs = mix.reset()
    alone = [SearchVecEnv(CONFIG, 3, seed=7), SearchVecEnv(BIG, 2, seed=8)]
    assert np.array_equal(obs["map"], np.concatenate([env.reset()["map"] for env in alone]))


def test_attribute_access_by_slot_and_bad_groups():
    mix = TeamMixVecEnv(_groups())
    mix.reset()
    assert mix.get_attr("n_agents") == [2] * 6 + [5] * 10
    assert mix.get_attr("n_agents", indices=[5, 6]) == [2, 5]
    assert mix.env_method("get_attr", "n_agents", indices=[0, 15]) == [[2] * 6, [5] * 10]
    mix.set_attr("render_mode", None)
    with pytest.raises(ValueError, match="subset of slots"):
        mix.set_attr("render_mode", None, indices=[0])
    assert mix.env_is_wrapped(VecMonitor) == [False] * 16
    with pytest.raises(ValueError, match="at least one"):
        TeamMixVecEnv([])
    with pytest.raises(ValueError, match=r"envs\[1\]"):
        TeamMixVecEnv([SearchVecEnv(CONFIG, 1), SearchVecEnv(replace(CONFIG, diagonal=True), 1)])
