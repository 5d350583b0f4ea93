"""PettingZoo ParallelEnv and the single-agent gymnasium view: API checkers, seeding, same dynamics as the engine."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test

import searchrl
from searchrl.envs.parallel_env import SearchParallelEnv
from searchrl.envs.single_env import SearchEnv
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld

CONFIG = WorldConfig(world_size=(10, 14), n_targets=(2, 3), n_agents=4, max_steps=30)


@pytest.mark.parametrize("age_channel", [False, True])
def test_pettingzoo_api_and_seed_tests(age_channel):
    config = WorldConfig(**{**CONFIG.__dict__, "belief_age": float(age_channel), "belief_age_channel": age_channel})
    parallel_api_test(SearchParallelEnv(config), num_cycles=80)
    parallel_seed_test(lambda: SearchParallelEnv(config), num_cycles=40)


@pytest.mark.parametrize("diagonal", [False, True])
def test_gymnasium_single_agent_view_passes_check_env(diagonal):
    env = SearchEnv(WorldConfig(world_size=(10, 14), n_targets=(2, 3), max_steps=30, diagonal=diagonal))
    check_env(env, skip_render_check=True)
    assert env.action_space.n == (9 if diagonal else 5)


def test_parallel_env_runs_the_same_world_as_the_batched_engine():
    env = SearchParallelEnv(CONFIG)
    world = SearchWorld(CONFIG, n_worlds=1, seed=3)
    obs, _ = env.reset(seed=3)
    maps, vector = world.reset()
    rng = np.random.default_rng(0)
    for _ in range(CONFIG.max_steps):
        for i, agent in enumerate(env.possible_agents):
            np.testing.assert_array_equal(obs[agent]["map"], maps[0, i])
            np.testing.assert_array_equal(obs[agent]["vector"], vector[0, i])
        actions = rng.integers(0, 5, size=4)
        obs, rewards, terms, _truncs, infos = env.step(dict(zip(env.possible_agents, actions.tolist(), strict=True)))
        tr = world.step(actions[None])
        np.testing.assert_array_equal([rewards[a] for a in env.possible_agents], tr.result.reward[0])
        if tr.result.done[0]:
            assert all(terms.values()) == bool(tr.result.terminated[0]) and not env.agents
            assert infos["agent_0"]["team_metrics"]["L"] == tr.metrics["L"][0]
            break
        maps, vector = tr.maps, tr.vector


def test_parallel_env_rejects_incomplete_actions_and_steps_after_the_end():
    env = searchrl.parallel_env(CONFIG)
    env.reset(seed=0)
    with pytest.raises(KeyError, match="agent_3"):
        env.step({a: 0 for a in env.possible_agents[:3]})
    env.agents = []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})


def test_render_returns_a_frame():
    env = SearchParallelEnv(CONFIG, render_mode="rgb_array")
    env.reset(seed=1)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape[2] == 3
