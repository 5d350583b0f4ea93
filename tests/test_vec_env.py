"""SearchVecEnv honours SB3's VecEnv contract (as DummyVecEnv does) with K worlds × N agents as K·N slots."""

from __future__ import annotations

import time

import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from stable_baselines3.common.vec_env import VecMonitor

from searchrl.envs.vec_env import SearchVecEnv
from searchrl.world.config import WorldConfig

CONFIG = WorldConfig(world_size=(10, 16), n_targets=(2, 4), n_agents=3, max_steps=6)


def _env(**kw) -> SearchVecEnv:
    return SearchVecEnv(CONFIG, n_worlds=4, seed=0, **kw)


def test_spaces_and_shapes():
    env = _env()
    assert env.num_envs == 12
    obs = env.reset()
    assert obs["map"].shape == (12, 5, 11, 11) and obs["map"].dtype == np.float32
    assert obs["vector"].shape == (12, 3)
    assert env.observation_space["map"].contains(obs["map"][0])
    assert env.action_space.n == 5
    assert len(env.reset_infos) == 12


def test_truncation_bootstraps_with_terminal_observation_and_team_metrics_once_per_world():
    env = _env()
    env.reset()
    rng = np.random.default_rng(0)
    episodes = 0
    for _ in range(30):
        _obs, rewards, dones, infos = env.step(rng.integers(0, 5, size=12))
        assert rewards.shape == (12,) and rewards.dtype == np.float32 and dones.shape == (12,)
        for w in range(4):
            slots = range(3 * w, 3 * w + 3)
            assert len({bool(dones[s]) for s in slots}) == 1  # a world's agents finish together
            if dones[3 * w]:
                for s in slots:
                    assert set(infos[s]) >= {"terminal_observation", "TimeLimit.truncated"}
                    term = infos[s]["terminal_observation"]
                    assert term["map"].shape == (5, 11, 11) and term["vector"].shape == (3,)
                # metrics reported on the first slot only, so loggers count world episodes, not agents
                assert "team_metrics" in infos[3 * w] and "episode" in infos[3 * w]
                assert all("team_metrics" not in infos[s] and "episode" not in infos[s] for s in slots[1:])
                truncated = infos[3 * w]["team_metrics"]["found_fraction"] < 1
                assert infos[3 * w]["TimeLimit.truncated"] == truncated
                assert infos[3 * w]["episode"]["l"] == infos[3 * w]["team_metrics"]["L"]
                episodes += 1
            else:
                assert all(not infos[s] for s in slots)
    assert episodes >= 4 * 4  # max_steps = 6: every world ends at least every 6 steps


def test_terminal_observation_differs_from_the_reset_observation():
    env = _env()
    env.reset()
    for _ in range(6):
        obs, _, dones, infos = env.step(np.zeros(12, np.int64))
    assert dones.all()
    assert not np.array_equal(infos[0]["terminal_observation"]["map"], obs["map"][0])


def test_seed_gives_the_same_rollout_and_observations_are_copies():
    def rollout(seed):
        env = _env()
        env.seed(seed)
        out = [env.reset()["map"]]
        for t in range(8):
            obs, r, _, _ = env.step(np.full(12, t % 5))
            out += [obs["map"], r]
        return out

    a, b, c = rollout(5), rollout(5), rollout(6)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0], c[0])
    env = _env()
    first = env.reset()
    kept = first["map"].copy()
    env.step(np.ones(12, np.int64))
    assert np.array_equal(first["map"], kept)  # SB3 keeps _last_obs across a step


def test_attribute_access_render_and_wrappers():
    env = _env(render_mode="rgb_array")
    env.reset()
    assert env.get_attr("render_mode") == ["rgb_array"] * 12
    assert env.get_attr("n_agents", indices=[0, 5]) == [3, 3]
    env.set_attr("label", "mine")  # set for every slot, read back by each
    assert env.get_attr("label", indices=[3]) == ["mine"]
    with pytest.raises(ValueError, match=r"^set_attr\('render_mode'\) on a subset of slots is not possible: all 12 "
                       r"slots share one world; pass indices=None$"):  # fmt: skip
        env.set_attr("render_mode", None, indices=[0])
    assert env.env_method("get_attr", "n_agents", indices=[1, 2]) == [[3] * 12, [3] * 12]
    assert env.env_method("get_attr", attr_name="n_agents", indices=[4]) == [[3] * 12]  # keyword arguments too
    assert env.env_is_wrapped(VecMonitor) == [False] * 12 and env.env_is_wrapped(VecMonitor, indices=[2]) == [False]
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    with pytest.raises(ValueError, match="render_mode"):
        SearchVecEnv(CONFIG, 1, render_mode="human")
    with pytest.raises(ValueError, match=r"^render_mode is None; create the env with render_mode='rgb_array'$"):
        _env().get_images()


def test_step_wait_without_actions_is_an_error():
    env = _env()
    with pytest.raises(ResetNeeded, match=r"^Cannot call env\.step\(\) before calling env\.reset\(\)$"):  # gymnasium's
        env.step_async(np.zeros(12, np.int64))
    env.reset()
    with pytest.raises(RuntimeError, match=r"^step_wait\(\) called before step_async\(\)$"):
        env.step_wait()
    with pytest.raises(ValueError, match=r"^actions have shape \(11,\): one action per slot, \(12,\)$"):
        env.step_async(np.zeros(11, np.int64))
    env.step(np.zeros(12, np.int64))
    with pytest.raises(RuntimeError, match="before step_async"):  # each step_async serves one step_wait
        env.step_wait()


def test_a_world_that_finds_its_last_target_on_its_last_step_has_terminated_not_truncated():
    """TimeLimit.truncated (SB3 bootstraps from the terminal observation) only where the time ran out with targets
    left; a team that finds the last one on the last step has ended its task. The episode's `t` is the seconds since
    the env was made, as SB3's Monitor writes it."""
    start = time.time()
    env = SearchVecEnv(WorldConfig(world_size=(10, 10), n_targets=(1, 1), n_agents=3, max_steps=3), 64, seed=0)
    env.reset()
    rng, both = np.random.default_rng(0), 0
    for _ in range(9):
        infos = env.step(rng.integers(0, 5, size=env.num_envs))[3]
        for info in infos[::3]:
            if "team_metrics" in info:
                found_all, last_step = info["team_metrics"]["found_fraction"] == 1, info["team_metrics"]["L"] == 3
                assert info["TimeLimit.truncated"] == (not found_all)
                both += found_all and last_step
                t = info["episode"]["t"]
                assert isinstance(t, float) and 0 <= t <= time.time() - start and t == round(t, 6)
    assert both > 0  # the case this test is for occurred


@pytest.mark.parametrize(("n_worlds", "n_agents"), [(1, 1), (4, 3)])
def test_seed_is_the_worlds_seed_whatever_the_slot_count(n_worlds, n_agents):
    """SB3's `seed(s)` gives slot i the seed s + i; the worlds take slot 0's, s itself: the same worlds as an env built
    with seed=s. One slot (one world of one agent) has no slot 1 to read."""
    config = WorldConfig(world_size=(10, 16), n_targets=(2, 4), n_agents=n_agents, max_steps=6)
    seeded = SearchVecEnv(config, n_worlds=n_worlds, seed=99)
    seeded.seed(5)
    built = SearchVecEnv(config, n_worlds=n_worlds, seed=5)
    np.testing.assert_array_equal(seeded.reset()["map"], built.reset()["map"])


def test_what_the_env_is_given_reaches_its_world_and_a_config_of_another_kind_is_named():
    """The scenario (its walls), an observation part (in the space and the observations) and a reward (paid in place
    of the world's) each reach the world, as a SearchWorld built with the same settings has them."""
    from searchrl.envs.parts import make_parts
    from searchrl.world.engine import SearchWorld
    from searchrl.world.obstacles import IidObstacles
    from searchrl.world.scenario import Scenario

    walls, parts = Scenario(IidObstacles(0.3, connected=True)), make_parts([("own_map", {"grid": 4})])
    env = SearchVecEnv(CONFIG, 2, seed=0, scenario=walls, parts=parts, reward=lambda config, result: -result.reward)
    twin = SearchWorld(CONFIG, 2, seed=0, scenario=walls, parts=parts)
    obs, (maps, _) = env.reset(), twin.reset()
    open_grid = SearchWorld(CONFIG, 2, seed=0)
    open_grid.reset()
    assert env.world.state.blocked.sum() > open_grid.state.blocked.sum()  # walls inside the grid, not only around it
    np.testing.assert_array_equal(env.world.state.blocked, twin.state.blocked)
    np.testing.assert_array_equal(obs["map"], maps.reshape(6, 5, 11, 11))
    assert obs["own_map"].shape == (6, *env.observation_space["own_map"].shape)
    actions = np.arange(6) % 5
    paid, result = env.step(actions)[1], twin.step(actions.reshape(2, 3)).result
    np.testing.assert_array_equal(paid, -result.reward.reshape(-1))
    with pytest.raises(ValueError, match=r"^config=\{'n_agents': 3\} is not allowed: a searchrl\.WorldConfig$"):
        SearchVecEnv({"n_agents": 3}, 2)
