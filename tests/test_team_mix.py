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
    mix.set_attr("label", "mine")  # every group's, read back by each slot
    assert mix.get_attr("label", indices=[0, 15]) == ["mine", "mine"]
    with pytest.raises(ValueError, match=r"^set_attr\('render_mode'\) on a subset of slots is not possible: slots "
                       r"share worlds; pass indices=None$"):  # fmt: skip
        mix.set_attr("render_mode", None, indices=[0])
    assert mix.env_method("get_attr", attr_name="n_agents", indices=[6]) == [[5] * 10]  # keyword arguments too
    assert mix.env_is_wrapped(VecMonitor) == [False] * 16 and mix.env_is_wrapped(VecMonitor, indices=[3]) == [False]
    with pytest.raises(ValueError, match=r"^envs=\[\] is not allowed: give at least one SearchVecEnv$"):
        TeamMixVecEnv([])
    with pytest.raises(ValueError, match=r"^envs\[1\] has other observation or action spaces than envs\[0\]: same Φ, "
                       r"fov and action set needed$"):  # fmt: skip
        TeamMixVecEnv([SearchVecEnv(CONFIG, 1), SearchVecEnv(replace(CONFIG, diagonal=True), 1)])


def test_a_mix_of_one_group_is_that_group():
    one, alone = (
        TeamMixVecEnv([SearchVecEnv(CONFIG, 3, seed=4, render_mode="rgb_array")]),
        SearchVecEnv(CONFIG, 3, seed=4),
    )
    assert one.render_mode == "rgb_array" and one.num_envs == 6
    obs, expected = one.reset(), alone.reset()
    assert one.reset_infos == [{}] * 6
    assert np.array_equal(obs["map"], expected["map"]) and np.array_equal(obs["vector"], expected["vector"])
    actions = np.random.default_rng(1).integers(0, 5, size=6)
    assert np.array_equal(one.step(actions)[1], alone.step(actions)[1])


SMALL = WorldConfig(world_size=(6, 9), n_targets=(1, 2), n_agents=2, max_steps=12)


def _two_resets(mix: TeamMixVecEnv, steps: int = 30) -> tuple[list, list]:
    """(observations, dones) of `mix` seeded once, reset, stepped past several episode ends (worlds ending at
    different steps), reset again without a seed, stepped again."""
    rng, seen, ends = np.random.default_rng(3), [], []
    mix.seed(7)
    for _ in range(2):
        seen.append(mix.reset()["map"].copy())
        for _ in range(steps):
            obs, _, dones, _ = mix.step(rng.integers(0, 5, size=mix.num_envs))
            seen.append(obs["map"].copy())
            ends.append(dones.copy())
    return seen, ends


def _mix() -> TeamMixVecEnv:
    return TeamMixVecEnv([SearchVecEnv(SMALL, 3, seed=0), SearchVecEnv(replace(SMALL, n_agents=3), 2, seed=1)])


def _alone() -> tuple[list, list]:
    """The same steps by each group on its own: seeded 7 and 8 for the first reset only."""
    envs = [SearchVecEnv(SMALL, 3, seed=7), SearchVecEnv(replace(SMALL, n_agents=3), 2, seed=8)]
    rng, seen, ends = np.random.default_rng(3), [], []
    for _ in range(2):
        seen.append(np.concatenate([env.reset()["map"] for env in envs]))
        for _ in range(30):
            actions = np.split(rng.integers(0, 5, size=12), [6])
            steps = [env.step(a) for env, a in zip(envs, actions, strict=True)]
            seen.append(np.concatenate([s[0]["map"] for s in steps]))
            ends.append(np.concatenate([s[2] for s in steps]))
    return seen, ends


def test_a_seed_seeds_one_reset_and_each_later_episode_is_the_groups_own():
    """Over several episodes, worlds ending at different steps, and a second reset: the mix is its groups on their
    own, and a seed given once seeds only the next reset (the second draws on from the groups' generators)."""
    (mixed, mixed_ends), (alone, alone_ends) = _two_resets(_mix()), _alone()
    assert len({tuple(np.flatnonzero(d)) for d in np.array(mixed_ends).T}) > 1  # slots end at different steps
    assert all(np.array_equal(a, b) for a, b in zip(mixed, alone, strict=True))
    assert np.array_equal(np.array(mixed_ends), np.array(alone_ends))
    assert not np.array_equal(mixed[0], mixed[31])  # the second reset drew new worlds


def test_a_planted_seed_that_outlives_its_reset_is_caught(monkeypatch):
    monkeypatch.setattr(TeamMixVecEnv, "_reset_seeds", lambda self: None)
    mixed, _ = _two_resets(_mix())
    alone, _ = _alone()
    assert not all(np.array_equal(a, b) for a, b in zip(mixed, alone, strict=True))
