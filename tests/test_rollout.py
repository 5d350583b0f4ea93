"""searchrl/controllers/rollout.py, the rollout planner: its scores are the worlds it imagines played out,
one agent at a time is the joint choice where agents cannot interact, and an episode is its seed's."""

from __future__ import annotations

import copy
import itertools
from types import SimpleNamespace

import numpy as np
import pytest

from searchrl.controllers.episodes import play_episodes
from searchrl.controllers.factory import heuristic_factory
from searchrl.controllers.registry import make_controller
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.streams import WorldStreams

CONFIG = WorldConfig(world_size=(20, 20), n_targets=(4, 4), n_distributions=(8, 8), n_agents=2, max_steps=40)


@pytest.fixture
def rollout():
    """The planner made as every app makes it, by the registry (which gives it the rules it plays on)."""

    def planner(config: WorldConfig, seed=0, **settings):
        return make_controller("rollout", config, seed=seed, settings=settings)

    return SimpleNamespace(Rollout=planner)


def _midway(config: WorldConfig, seeds: list[int], steps: int):
    """Worlds of `seeds` played `steps` steps by B's teacher, and that teacher."""
    world = SearchWorld.from_maps(config, seeds, WorldStreams([[s, 0] for s in seeds]), observe=False)
    teacher = make_controller(
        "greedy_target", config, seed=WorldStreams([[s, 1] for s in seeds]), settings={"reach": 2}
    )
    teacher.reset(world.state, np.ones(len(seeds), bool))
    for _ in range(steps):
        world.step(teacher.act(world.state, None, None))
    return world, teacher


@pytest.mark.parametrize("horizon", [0, 5])
def test_a_score_in_the_true_world_is_that_world_played_out_with_the_same_numbers(rollout, horizon):
    """With `truth`, the score of a first joint move in sample j is the targets found when a copy of the real world
    takes that move and the base rule plays on to the horizon, drawing sample j's numbers: the privileged probe."""
    world, _ = _midway(CONFIG, [5, 6], 9)
    planner = rollout.Rollout(CONFIG, seed=WorldStreams([[1], [2]]), samples=3, chunk=3, stop=0, horizon=horizon,
                              truth=True, value="sampled")  # fmt: skip
    planner.reset(world.state, np.ones(2, bool))
    worlds = np.array([1, 0])
    first = np.array([[[0, 1], [3, 2], [4, 4]], [[1, 1], [2, 0], [0, 3]]])  # (W, C, N): candidate joint moves
    keys = [[11, 0], [12, 1]]
    targets = planner.imagine(world.state, worlds, np.array([7, 8]))
    scores = planner.score(world.state, worlds, first, targets, keys)
    assert scores.shape == (2, 3, 3)
    end = CONFIG.max_steps if horizon == 0 else int(world.state.t[0]) + horizon
    for g, c, j in itertools.product(range(2), range(3), range(3)):
        replay = copy.deepcopy(world)
        k = int(worlds[g])
        for value in vars(replay.state).values():
            if isinstance(value, np.ndarray) and value.shape[:1] == (2,):
                value[:] = value[[k, k]]
        generator = WorldStreams([[*keys[g], 0, 0]]).generators[0]
        base_generator = WorldStreams([[*keys[g], 0, 1]]).generators[0]
        replay.rng = _Skipping(generator, j, 3)
        base = make_controller("greedy_target", CONFIG, seed=_Skipping(base_generator, j, 3), settings={"reach": 2})
        base.reset(replay.state, np.ones(2, bool))
        replay.step(np.stack([first[g, c]] * 2))
        while replay.state.t[0] < end and replay.state.n_found[0] < replay.state.n_targets[0]:
            replay.step(base.act(replay.state, None, None))
        assert scores[g, c, j] == replay.state.n_found[0], (g, c, j)


class _Skipping(WorldStreams):
    """Two worlds that both draw what sample j of m draws from one group generator: the rows (m, ...) drawn, row j."""

    def __init__(self, generator: np.random.Generator, j: int, m: int) -> None:
        self.generator, self.j, self.m = generator, j, m
        self.generators = [generator, generator]

    def random(self, size):
        row = self.generator.random((self.m, *size[1:]))[self.j]
        return np.stack([row, row])

    def integers(self, low, high, size):
        row = self.generator.integers(low, high, size=(self.m, *size[1:]))[self.j]
        return np.stack([row, row])


def test_one_agent_at_a_time_is_the_joint_choice_where_agents_cannot_interact(rollout):
    """Over one step (horizon 1), with communication off and the agents far apart, each agent's finds depend on its
    own move only: the sequential choice is the best of the 25 joint moves scored on the same samples."""
    config = WorldConfig(world_size=(40, 40), n_targets=(8, 8), n_distributions=(8, 8), n_agents=2,
                         communication=False)  # fmt: skip
    world, _ = _midway(config, [3, 4, 5], 0)
    world.state.pos[:, 0], world.state.pos[:, 1] = (5, 5), (33, 33)  # never within each other's view
    world.state.occupant[:] = -1
    for k in range(3):
        for i, (r, c) in enumerate(world.state.pos[k]):
            world.state.occupant[k, r + world.state.halo, c + world.state.halo] = i
    planner = rollout.Rollout(config, seed=WorldStreams([[1], [2], [3]]), samples=16, chunk=16, stop=0, horizon=1,
                              truth=True, value="sampled")  # fmt: skip
    planner.reset(world.state, np.ones(3, bool))
    worlds, keys = np.arange(3), np.array([41, 42, 43])
    base = np.zeros((3, 2), np.int64)  # stay: a choice differs from the base move only for a better move
    sequential = planner.plan(world.state, worlds, base, keys)
    joint = np.array(list(itertools.product(range(config.n_actions), repeat=2)))  # (25, 2)
    targets = planner.imagine(world.state, worlds, keys)
    scores = planner.score(world.state, worlds, np.repeat(joint[None], 3, axis=0), targets, [[k] for k in keys])
    means = scores.mean(axis=2)  # (W, 25)
    picked = [int(np.flatnonzero((joint == sequential[w]).all(axis=1))[0]) for w in range(3)]
    assert np.allclose(means[worlds, picked], means.max(axis=1))  # the sequential moves reach the joint optimum
    assert (sequential != base).any()  # and the case is not trivial: some agent leaves the base move


def test_the_same_seed_plays_the_same_episode(rollout):
    factory = heuristic_factory("rollout", {"samples": 4, "horizon": 6})
    seeds, keys = [31, 32], [[0, 1], [0, 2]]
    one = play_episodes(factory, CONFIG, seeds, keys, needs_observation=False)
    two = play_episodes(factory, CONFIG, seeds, keys, needs_observation=False)
    other = play_episodes(factory, CONFIG, seeds, [[9, 1], [9, 2]], needs_observation=False)
    assert all(np.array_equal(one[name], two[name]) for name in one)
    assert any(not np.array_equal(one[name], other[name]) for name in one)


def test_the_expected_finds_are_the_mean_of_the_sampled_finds(rollout):
    """The noiseless score is the expectation the sampled score estimates: over 400 imagined placements of the
    unfound targets, the sampled mean lies within four standard errors of it, for every candidate move."""
    world, _ = _midway(CONFIG, [8], 6)
    scores = {}
    for value in ("expected", "sampled"):
        planner = rollout.Rollout(CONFIG, seed=WorldStreams([[1]]), samples=400, chunk=400, stop=0, horizon=12,
                                  value=value)  # fmt: skip
        planner.reset(world.state, np.ones(1, bool))
        first = np.repeat(np.zeros((1, 1, 2), np.int64), CONFIG.n_actions, axis=1)
        first[0, :, 0] = np.arange(CONFIG.n_actions)
        targets = planner.imagine(world.state, np.array([0]), np.array([5]))
        scores[value] = planner.score(world.state, np.array([0]), first, targets, [[3]])[0]  # (C, M)
    sampled, expected = scores["sampled"], scores["expected"]
    error = sampled.std(axis=1, ddof=1) / np.sqrt(sampled.shape[1])
    assert (np.abs(sampled.mean(axis=1) - expected.mean(axis=1)) < 4 * error + 1e-9).all()
    assert expected.std(axis=1).max() < sampled.std(axis=1).min()  # and it is the quieter score
    assert np.ptp(expected.mean(axis=1)) > 0  # the moves differ


def test_a_neighbourhood_of_one_is_the_whole_team_where_agents_cannot_interact(rollout):
    """Agents far apart with communication off, over three steps: rolling out the deciding agent alone (team=1) or
    with one teammate chooses what rolling out the whole team chooses; the neighbourhood is the nearest agents."""
    config = WorldConfig(world_size=(40, 40), n_targets=(8, 8), n_distributions=(8, 8), n_agents=3,
                         communication=False)  # fmt: skip
    world, _ = _midway(config, [3, 4], 0)
    world.state.pos[:] = np.array([[5, 5], [33, 33], [5, 33]])  # at least 28 cells apart
    world.state.occupant[:] = -1
    for k in range(2):
        for i, (r, c) in enumerate(world.state.pos[k]):
            world.state.occupant[k, r + world.state.halo, c + world.state.halo] = i
    moves = {}
    for team in (0, 1, 2):
        planner = rollout.Rollout(config, seed=WorldStreams([[1], [2]]), samples=2, chunk=2, stop=0, horizon=3,
                                  team=team)  # fmt: skip
        planner.reset(world.state, np.ones(2, bool))
        moves[team] = planner.plan(world.state, np.arange(2), np.zeros((2, 3), np.int64), np.array([5, 6]))
    assert np.array_equal(moves[1], moves[0]) and np.array_equal(moves[2], moves[0])
    assert (moves[0] != 0).any()
    world.state.pos[1, 1] = (12, 30)  # world 1: agent 1 now 7 cells from agent 2, agent 0 still 28
    near = rollout.Rollout(config, samples=2, team=2)
    assert near.members(world.state, np.arange(2), 2).tolist() == [[0, 2], [1, 2]]  # a tie goes to the lower index


def test_bench_eval_times_the_planner_and_its_own_worlds_and_refuses_in_one_line(rollout, capsys):
    """`bench eval --controller rollout`: a row with the planner's decisions/s and its
    rollouts' rate beside the engine's on batches of their size (one map: 5 moves x 1 sample, 5 worlds)."""
    import json

    from searchrl.bench.__main__ import main

    settings = '{"samples": 1, "horizon": 3}'
    assert main(["eval", "--controller", "rollout", "--settings", settings,
                 "--cells", "n20_N2", "--maps", "1", "--threads", "1", "--json"]) == 0  # fmt: skip
    row = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert row["case"] == "rollout_n20_N2_1maps_1repeats" and row["inner_batch"] == 5
    assert row["inner_agent_steps_per_s"] > 0 and row["engine_agent_steps_per_s"] > 0
    assert row["inner_share"] == pytest.approx(row["inner_agent_steps_per_s"] / row["engine_agent_steps_per_s"], 1e-3)
    with pytest.raises(SystemExit):
        main(["eval", "--controller", "rollout", "--settings", '{"sample": 2}'])
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "--settings={\"sample\": 2} is not allowed: rollout takes no setting 'sample'" in err[-1]
    assert main(["eval", "--extensions", "no_such_module", "--controller", "surfing"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "extensions: 'no_such_module' cannot be imported" in err[0]


def test_a_base_that_is_not_a_rule_is_refused_in_one_line():
    """The registry gives the planner its rules: a typo is refused with the nearest name, the planner itself too."""
    from searchrl.world.config import ConfigError

    with pytest.raises(
        ConfigError, match=r"^controller\.base='greedy_targt' is not allowed: one of .*greedy_target'\?\)$"
    ):
        make_controller("rollout", CONFIG, settings={"base": "greedy_targt"})
    with pytest.raises(ConfigError, match=r"^controller\.base='rollout' is not allowed: the planner's base is a rule$"):
        make_controller("rollout", CONFIG, settings={"base": "rollout"})
