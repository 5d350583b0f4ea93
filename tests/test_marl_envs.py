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


SMALL = WorldConfig(world_size=(10, 10), n_targets=(2, 2), n_agents=2, max_steps=5)


def _says(error: type[Exception], line: str, call) -> None:
    """`call()` raises `error` whose message is `line`, whole."""
    with pytest.raises(error) as raised:
        call()
    assert raised.value.args[0] == line


@pytest.mark.parametrize("make", [SearchParallelEnv, SearchEnv])
def test_the_envs_refuse_a_bad_config_render_mode_or_seed_in_their_whole_line(make):
    _says(ValueError, "config='b' is not allowed: a searchrl.WorldConfig or None", lambda: make("b"))
    _says(ValueError, "render_mode='human' is not allowed: None or 'rgb_array'", lambda: make(render_mode="human"))
    env = make(SMALL)
    for seed in (-1, 1.5, "7"):
        line = f"seed={seed!r} is not allowed: None or an integer >= 0"
        _says(ValueError, line, lambda seed=seed: env.reset(seed=seed))
    env.reset(seed=np.int64(3))  # a numpy integer is a seed (gymnasium's own reset takes Python ints only)
    default = make()  # no config: the paper's world (a single agent for the gymnasium view)
    assert default.config == WorldConfig() if make is SearchParallelEnv else default._env.config.n_agents == 1


def test_the_parallel_env_refuses_agents_and_actions_in_their_whole_line():
    """Out of order, wrong types and names: the PettingZoo env's own lines, before the engine sees an action."""
    env = SearchParallelEnv(SMALL)
    assert env.agents == []  # no live agent before the first reset
    last = "one of possible_agents, agent_0 … agent_1"
    _says(ValueError, f"agent='agent_2' is not allowed: {last}", lambda: env.observation_space("agent_2"))
    _says(ValueError, f"agent='x' is not allowed: {last}", lambda: env.action_space("x"))
    before = "step() called before reset() or after the episode ended: call reset() first"
    _says(RuntimeError, before, lambda: env.step({"agent_0": 0, "agent_1": 0}))
    env.reset(seed=0)
    _says(ValueError, "actions=[0, 0] is not allowed: a dict {agent name: action}", lambda: env.step([0, 0]))
    _says(KeyError, "actions missing for ['agent_1']: every live agent acts at every step",
          lambda: env.step({"agent_0": 0}))  # fmt: skip
    _says(ValueError, "actions for ['agent_7'] are not allowed: the live agents are ['agent_0', 'agent_1']",
          lambda: env.step({"agent_0": 0, "agent_1": 0, "agent_7": 1}))  # fmt: skip
    for action in (1.0, "1", True, -1, 5, np.float32(2), np.array([1]), np.array(1.5)):
        _says(ValueError, f"actions['agent_0']={action!r} is not allowed: an integer in [0, 5)",
              lambda action=action: env.step({"agent_0": action, "agent_1": 0}))  # fmt: skip
    env.step({"agent_0": np.int32(4), "agent_1": np.array(2)})  # numpy integers and 0-d arrays are integers
    with pytest.raises(ValueError, match="seed=-1 is not allowed"):
        SearchWorld(env.config, 2, seed=-1)  # the engine under the VecEnv and the env checks its seed the same way


def test_envs_stepped_before_their_reset_say_so_as_gymnasium_and_pettingzoo_do():
    """Out of order: the VecEnv raises gymnasium's ResetNeeded, the world a one-line RuntimeError, the PettingZoo env
    its own line; none reaches the kernels (which raised numba's SystemError on the empty state)."""
    from gymnasium.error import ResetNeeded

    from searchrl.envs.vec_env import SearchVecEnv

    env = SearchVecEnv(SMALL, n_worlds=2, seed=0)
    with pytest.raises(ResetNeeded, match=r"Cannot call env.step\(\) before calling env.reset\(\)"):
        env.step(np.zeros(env.num_envs, np.int64))
    env.reset()
    env.step(np.zeros(env.num_envs, np.int64))
    with pytest.raises(RuntimeError, match=r"step\(\) called before reset\(\)"):
        SearchWorld(SMALL, 2, seed=0).step(np.zeros((2, 2), np.int64))


def test_an_episode_ends_for_every_agent_at_max_steps_with_the_teams_metrics_and_waits_for_reset():
    env = SearchParallelEnv(WorldConfig(world_size=(20, 20), n_targets=(8, 8), n_agents=2, max_steps=5))
    env.reset(seed=1)
    for t in range(1, 6):
        _, _, terms, truncs, infos = env.step({"agent_0": 0, "agent_1": 0})  # both stay: not every target found
        assert not any(terms.values()) and all(truncs.values()) == (t == 5) and set(truncs) == {"agent_0", "agent_1"}
        assert all(("team_metrics" in info) == (t == 5) for info in infos.values())
    assert env.agents == [] and env.world_state.t[0] == 5  # the world is not reset under the agents' last step
    assert infos["agent_1"]["team_metrics"]["L"] == 5.0


def test_the_envs_draw_their_scenarios_worlds_and_observe_their_parts():
    from searchrl.envs.parts import make_parts
    from searchrl.world.scenario import Scenario

    walls = Scenario.from_dict({"obstacles": {"kind": "iid", "density": 0.3}})
    open_grid = SearchParallelEnv(SMALL)
    open_grid.reset(seed=0)
    border = open_grid.world_state.blocked.sum()  # outside the world
    for env in (SearchParallelEnv(SMALL, scenario=walls), SearchEnv(SMALL, scenario=walls)._env):
        env.reset(seed=0)
        assert env.world_state.blocked.sum() > border  # walls inside the world too
    env = SearchParallelEnv(SMALL, parts=make_parts([("own_map", {"grid": 4})]))
    obs, _ = env.reset(seed=0)
    for i, agent in enumerate(env.possible_agents):
        space = env.observation_space(agent)
        assert space.contains(obs[agent]) and space["own_map"].shape == obs[agent]["own_map"].shape == (3, 4, 4)
        np.testing.assert_array_equal(obs[agent]["own_map"], env.world.parts["own_map"][0, i])


def test_the_gymnasium_view_renders_when_asked():
    env = SearchEnv(SMALL, render_mode="rgb_array")
    env.reset(seed=0)
    assert env.render_mode == "rgb_array" and env.render().ndim == 3 and SearchEnv(SMALL).render() is None
