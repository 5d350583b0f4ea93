"""The research parts under analysis/ that the lab's long trainings use: the team reward registered through
`extensions`, and carrying a training to another machine through runs/lab/ (analysis/carry_runs.py)."""

from __future__ import annotations

import importlib
import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from searchrl.controllers.registry import make_controller
from searchrl.envs.rewards import RewardConfig, make_reward
from searchrl.policies.slim import ROLLOUT_STATE, is_slim, weights_sha256
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.step import StepResult
from searchrl.world.streams import WorldStreams
from tests.registries import isolated_registries
from tests.test_train import TINY, _compose, _run

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "analysis"))
import carry_runs  # noqa: E402  (analysis/ is no package)

import analysis.team_reward  # noqa: E402,F401  (registers `team_found` and `own_found`)


def _result(found: np.ndarray) -> StepResult:
    k, n = found.shape
    return StepResult(reward=np.full((k, n), 7.0, np.float32), terminated=np.zeros(k, bool),
                      truncated=np.zeros(k, bool), collided=np.zeros((k, n), bool), targets_found=found,
                      info_collected=np.ones((k, n)), comm_gain=np.ones((k, n)),
                      comm_pairs=np.zeros(k, np.int64))  # fmt: skip


def test_the_team_reward_pays_every_agent_its_worlds_finds_and_nothing_else():
    found = np.array([[0, 2, 0], [0, 0, 0], [1, 1, 3]], np.int64)
    reward = make_reward(RewardConfig("team_found"))(WorldConfig(), _result(found))
    assert reward.dtype == np.float32 and reward.shape == (3, 3)
    assert reward.tolist() == [[2, 2, 2], [0, 0, 0], [5, 5, 5]]  # the paper's reward (7), information, ignored
    assert reward.flags.writeable  # a fresh array, not a read-only broadcast view


def test_the_own_reward_pays_each_agent_its_own_finds_and_nothing_else():
    found = np.array([[0, 2, 0], [1, 1, 3]], np.int64)
    reward = make_reward(RewardConfig("own_found"))(WorldConfig(), _result(found))
    assert reward.dtype == np.float32 and reward.tolist() == [[0, 2, 0], [1, 1, 3]]


@pytest.mark.app
def test_a_carried_run_holds_its_newest_checkpoint_and_resumes_elsewhere(tmp_path):
    run = tmp_path / "train" / "tiny"
    _run(run, ["+model=b", *TINY])
    whole = pd.read_csv(run / "progress.csv")["time/total_timesteps"].tolist()
    (run / "checkpoints" / "step_2048.zip").unlink()  # as if stopped after its checkpoint at 1024: rows past it stay
    (run / "model.zip").unlink()
    for path in (run / "checkpoints").glob("*.zip"):  # searchrl's checkpoints leave out the rollout in progress
        assert not set(json.loads(zipfile.ZipFile(path).read("data"))) & set(ROLLOUT_STATE)

    lab = tmp_path / "lab"
    carried = carry_runs.carry(run, lab)
    assert carried == lab / "tiny"
    assert sorted(p.name for p in (carried / "checkpoints").iterdir()) == ["step_1024.zip"]
    assert weights_sha256(carried / "checkpoints" / "step_1024.zip") == weights_sha256(run / "checkpoints" /
                                                                                     "step_1024.zip")  # fmt: skip
    assert not (carried / "tensorboard").exists() and (carried / "config.yaml").read_bytes() == (
        run / "config.yaml").read_bytes()  # fmt: skip

    elsewhere = tmp_path / "other_machine" / "tiny"
    shutil.copytree(carried, elsewhere)
    from searchrl.train.app import train

    overrides = [f"resume={elsewhere}", "total_timesteps=2048"]
    train(_compose(overrides), elsewhere / "resumed", overrides)
    steps = pd.read_csv(elsewhere / "progress.csv")["time/total_timesteps"].tolist()
    assert steps == whole  # the rows past 1024 replaced, not doubled
    assert (elsewhere / "model.zip").is_file()

    carried_again = carry_runs.carry(elsewhere, lab)  # the newer checkpoint replaces the older
    assert sorted(p.name for p in (carried_again / "checkpoints").iterdir()) == ["step_2048.zip"]
    assert not is_slim(carried_again / "checkpoints" / "step_2048.zip")  # Adam's moments carried

    assert carry_runs.main(["--to", str(tmp_path / "gpu"), "--without-moments", str(elsewhere)]) == 0
    light = tmp_path / "gpu" / "tiny" / "checkpoints" / "step_2048.zip"
    assert is_slim(light) and weights_sha256(light) == weights_sha256(elsewhere / "checkpoints" / "step_2048.zip")


@pytest.mark.parametrize("argv", [[], ["--to"], ["--to", "lab"], ["--moments", "run"]])
def test_the_carry_command_refuses_what_it_does_not_know_in_one_line(argv, capsys):
    assert carry_runs.main(argv) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_carrying_a_folder_without_checkpoints_is_refused_in_one_line(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "config.yaml").write_text("seed: 0\n")
    with pytest.raises(SystemExit, match=r"holds no checkpoints/step_<n>.zip"):
        carry_runs.carry(tmp_path / "run", tmp_path / "lab")


@pytest.fixture
def lookahead():
    """analysis/lookahead.py, its controller registered for this test only."""
    with isolated_registries("analysis"):
        yield importlib.import_module("analysis.lookahead")


def test_a_lookahead_copy_steps_as_the_world_it_copies(lookahead):
    config = WorldConfig(world_size=(20, 20), n_targets=(4, 4), n_distributions=(8, 8), n_agents=3)
    source = SearchWorld.from_maps(config, [5, 6, 7], WorldStreams([[0], [1], [2]]), observe=False)
    teacher = make_controller("greedy_target", config, seed=WorldStreams([[3], [4], [5]]), settings={"reach": 2})
    teacher.reset(source.state, np.ones(3, bool))
    for _ in range(12):
        source.step(teacher.act(source.state, None, None))
    copies = SearchWorld(config, 2, auto_reset=False, observe=False)
    lookahead.copy_world(source.state, 1, copies)
    source.rng.restart([1], [[9]])  # world 1 and both copies draw the same numbers from here on
    copies.rng = WorldStreams([[9], [9]])
    rng = np.random.default_rng(0)
    for _ in range(20):
        moves = rng.integers(0, config.n_actions, (3, 3))
        source.step(moves)
        copies.step(moves[[1, 1]])
    for name in ("pos", "belief", "p", "u", "target_found", "found_grid", "swept", "n_found", "t", "ep_return"):
        mine, theirs = getattr(copies.state, name), getattr(source.state, name)
        assert np.array_equal(mine[0], theirs[1]) and np.array_equal(mine[1], theirs[1]), name


def test_imagined_targets_lie_where_unfound_targets_can_and_differ_by_sample(lookahead):
    p_now = np.zeros((12, 12))
    p_now[2:8, 3:9] = np.linspace(0.1, 1.0, 36).reshape(6, 6)  # no target outside this block
    free = np.ones((12, 12), bool)
    free[7, 8] = free[7, 7] = False  # found targets' cells (the likeliest two): no second target there
    prior_u = np.full((12, 12), 0.5)
    prior_u[0, 0] = 1.0  # §4.1.4 keeps a cell with probability 1 − u / max u: one half here
    draws = lookahead.posterior_targets(p_now, prior_u, free, 5, 20, np.random.default_rng(0))
    assert len(draws) == 20 and all(d.shape == (5, 2) and d.dtype == np.int64 for d in draws)
    for cells in draws:
        assert len({tuple(c) for c in cells}) == 5  # distinct cells
        assert (p_now[cells[:, 0], cells[:, 1]] > 0).all() and free[cells[:, 0], cells[:, 1]].all()
    assert not np.array_equal(draws[0], draws[1])


def test_every_imagined_copy_holds_its_samples_draw_and_none_the_true_targets(lookahead):
    config = WorldConfig(world_size=(20, 20), n_targets=(4, 4), n_distributions=(8, 8), n_agents=2)
    source = SearchWorld.from_maps(config, [5], WorldStreams([[0]]), observe=False)
    planner = lookahead.Lookahead(config, samples=3)
    planner.reset(source.state, np.ones(1, bool))
    copies = SearchWorld(config, 2 * config.n_actions * 3, auto_reset=False, observe=False)  # (agent, move, sample)
    lookahead.copy_world(source.state, 0, copies)
    planner.imagine_targets(copies, source.state, 0, np.random.default_rng(1))
    truth = {tuple(cell) for cell in source.state.target_pos[0, :4]}
    drawn = [{tuple(cell) for cell in copies.state.target_pos[w, :4]} for w in range(copies.n_worlds)]
    assert all(cells == drawn[w % 3] for w, cells in enumerate(drawn))  # sample l's draw, whatever the move
    assert len({frozenset(cells) for cells in drawn}) == 3 and truth not in drawn


def test_the_lookahead_leaves_the_teachers_move_only_for_a_surely_better_one(lookahead):
    found = np.zeros((3, 3, 4))  # (agents, moves, samples): targets found after each move
    found[0] = [[2, 3, 2, 3], [2, 3, 2, 3], [1, 1, 1, 1]]  # moves 0 and 1 tie
    found[1] = [[1, 1, 1, 1], [2, 2, 2, 2], [3, 0, 4, 2]]  # 1 is better by 1 in every sample, 2 by 1.25 on average
    found[2] = [[2, 2, 2, 2], [2, 6, 0, 2], [2, 2, 2, 2]]  # 1 is better on average (+0.5), by noise
    for confidence, want in ((2.0, [1, 1, 0]), (0.0, [1, 2, 1])):
        assert lookahead.choose(found, np.array([1, 0, 0]), confidence).tolist() == want, confidence
    assert lookahead.choose(found, np.array([0, 1, 1]), 2.0).tolist() == [0, 1, 1]  # the teacher's, or better


@pytest.mark.slow  # two evaluations in their own processes, about a minute
def test_the_lookahead_evaluates_through_extensions_and_repeats_its_episodes(tmp_path):
    from searchrl.evaluate.results import load

    args = ["controller=lookahead", "extensions=[analysis.lookahead]", "controller.samples=2",
            "controller.horizon=3", "+model=b", "grid.world_sizes=[20]", "grid.n_targets=[4]",
            "grid.n_distributions=[8]", "grid.max_agents=[2]", "grid.maps_per_cell=1", "grid.repeats=1",
            "progress_bar=false", "threads=1"]  # fmt: skip
    runs = []
    for folder in ("a", "b"):  # as a user runs it: the entry point imports the extension before Hydra composes
        done = subprocess.run([sys.executable, "-m", "searchrl.evaluate", *args, f"out_dir={tmp_path / folder}"],
                              cwd=ROOT, capture_output=True, text=True, timeout=300)  # fmt: skip
        assert done.returncode == 0, done.stderr[-2000:]
        runs.append(load(tmp_path / folder))
    first, again = runs
    assert (first.controller == "lookahead").all() and len(first) == 2  # cells (20, 1), (20, 2)
    assert first.found_fraction.tolist() == again.found_fraction.tolist() and first.L.tolist() == again.L.tolist()


@pytest.fixture
def rollout_own():
    """analysis/rollout_own.py, its controller registered for this test only."""
    with isolated_registries("analysis"):
        yield importlib.import_module("analysis.rollout_own")


def test_the_decentralised_planner_is_the_shipped_one_for_a_lone_agent_and_imagines_each_agent_alone(rollout_own):
    """With one agent its own belief is the team's map and it is the whole team: the same episodes as the shipped
    planner's, move for move. With two, each agent's imagined worlds hold it alone, on its own belief."""
    from searchrl.controllers.episodes import play_episodes
    from searchrl.controllers.factory import heuristic_factory

    lone = WorldConfig(world_size=(20, 20), n_targets=(4, 4), n_distributions=(8, 8), n_agents=1, max_steps=30)
    seeds, keys = [31, 32], [[0, 1], [0, 2]]
    played = {
        name: play_episodes(heuristic_factory(name, {"horizon": 6}), lone, seeds, keys, needs_observation=False)
        for name in ("rollout_own", "rollout")
    }
    assert all(np.array_equal(played["rollout_own"][k], played["rollout"][k]) for k in played["rollout"])
    pair = WorldConfig(world_size=(20, 20), n_targets=(4, 4), n_distributions=(8, 8), n_agents=2, max_steps=30)
    world = SearchWorld(pair, 2, seed=3, observe=False)
    world.reset()
    planner = make_controller("rollout_own", pair, seed=0, settings={"horizon": 4})
    planner.reset(world.state, np.ones(2, bool))
    seen = []
    original = planner.score
    planner.score = lambda own, *args: (seen.append(own.p), original(own, *args))[1]
    moves = planner.act(world.state, None, None)
    assert moves.shape == (2, 2) and planner.work["agents"] == 1
    assert len(seen) == 2 and all(np.shares_memory(p, world.state.belief) for p in seen)  # each agent's own map
    with pytest.raises(ConfigError, match=r"^controller\.team=2 is not allowed: 1 \(each agent imagined alone\) or 0"):
        make_controller("rollout_own", pair, settings={"team": 2})
    known = rollout_own.known_to(world.state, 1)  # what agent 1 knows: its map is the world's and every agent's
    assert np.array_equal(known.p, world.state.belief[:, 1, 0]) and np.array_equal(known.u, world.state.belief[:, 1, 1])
    assert (
        all(np.array_equal(known.belief[:, j], world.state.belief[:, 1]) for j in range(2)) and not known.merged.any()
    )
    with_team = make_controller("rollout_own", pair, seed=0, settings={"horizon": 4, "team": 0})
    with_team.reset(world.state, np.ones(2, bool))
    assert with_team.act(world.state, None, None).shape == (2, 2) and with_team.work["agents"] == 2
