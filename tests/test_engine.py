"""SearchWorld: auto-reset per world, final observations, episode metrics, determinism; the bench CLI."""

from __future__ import annotations

import copy
import json
import pickle

import numpy as np
import pytest
import torch

from searchrl.bench.__main__ import main as bench_main
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.observe import observe
from searchrl.world.reset import reset_worlds
from searchrl.world.state import allocate
from searchrl.world.step import check_actions, step
from searchrl.world.sums import numpy_sum

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)


def _rollout(seed: int, steps: int, config: WorldConfig, k: int = 4):
    world = SearchWorld(config, n_worlds=k, seed=seed)
    maps, vec = world.reset()
    out = [(maps.copy(), vec.copy())]
    act_rng = np.random.default_rng(seed + 100)
    for _ in range(steps):
        tr = world.step(act_rng.integers(0, config.n_actions, size=(k, config.n_agents)))
        out.append((tr.maps.copy(), tr.vector.copy(), tr.result.reward.copy(), tr.result.done.copy()))
    return out


def test_same_seed_same_trajectory_different_seed_differs():
    config = WorldConfig(world_size=(12, 20), n_targets=(2, 4), n_agents=5, max_steps=30)
    a, b, c = _rollout(3, 70, config), _rollout(3, 70, config), _rollout(4, 70, config)
    for x, y in zip(a, b, strict=True):
        for u, v in zip(x, y, strict=True):
            np.testing.assert_array_equal(u, v)
    assert any(not np.array_equal(x[0], y[0]) for x, y in zip(a, c, strict=True))


def test_finished_worlds_reset_alone_with_final_observation_and_metrics():
    config = WorldConfig(world_size=(10, 14), n_targets=(1, 3), n_agents=3, max_steps=7)
    world = SearchWorld(config, n_worlds=3, seed=0)
    world.reset()
    rng = np.random.default_rng(0)
    for _ in range(7):
        before = world.state.copy()
        tr = world.step(rng.integers(0, config.n_actions, size=(3, 3)))
        done = tr.result.done
        # Every world is truncated at max_steps unless it terminated earlier.
        assert (tr.result.truncated == ((before.t + 1 >= 7) & ~tr.result.terminated)).all()
        if done.any():
            m = tr.metrics
            assert ((m["L"][done] >= 1) & (m["L"][done] <= 7)).all()
            assert ((m["found_fraction"][done] >= 0) & (m["found_fraction"][done] <= 1)).all()
            assert (m["found_fraction"][tr.result.terminated] == 1.0).all()
            assert (world.state.t[done] == 0).all()  # reset
            # The final observation's vector shows the remaining targets at the end, not after reset.
            remaining = (before.n_targets - before.n_found)[done]
            assert (tr.final_vector[done][:, :, 2] <= remaining[:, None] / before.n_targets[done][:, None]).all()
        assert (world.state.t[~done] == before.t[~done] + 1).all()
        # Only the reset worlds are observed again: the step's observation is the whole state's, bit for bit.
        maps, vector = observe(config, world.state)
        np.testing.assert_array_equal(tr.maps, maps)
        np.testing.assert_array_equal(tr.vector, vector)


@pytest.mark.parametrize("scenario", [{}, {"obstacles": {"kind": "iid", "density": 0.2}}])
def test_a_world_that_starts_another_episode_plays_it_as_a_fresh_world_would(scenario):
    """`start_episodes` in worlds that have stepped gives them the episode `from_maps` starts from the same map seed
    and stream: the same state and observation, then the same steps; the world left alone is untouched."""
    from searchrl.world.scenario import Scenario
    from searchrl.world.streams import WorldStreams

    config, scenario = WorldConfig(world_size=(12, 20), n_targets=(4, 8), n_agents=6), Scenario.from_dict(scenario)
    fresh = SearchWorld.from_maps(config, [11, 12, 13], WorldStreams([(1, 0), (2, 0), (3, 0)]), scenario)
    used = SearchWorld.from_maps(config, [5, 6, 13], WorldStreams([(7, 0), (8, 0), (9, 0)]), scenario)
    rng = np.random.default_rng(0)
    for _ in range(7):
        used.step(rng.integers(0, config.n_actions, size=(3, config.n_agents)))
    left = copy.deepcopy(used.state)
    used.start_episodes([2, 0], [13, 11], [(3, 0), (1, 0)])  # map 13 was drawn before: written again, not redrawn
    for _ in range(40):
        actions = rng.integers(0, config.n_actions, size=(3, config.n_agents))
        for k in (0, 2):
            np.testing.assert_array_equal(used.observation[0][k], fresh.observation[0][k])
            np.testing.assert_array_equal(used.observation[1][k], fresh.observation[1][k])
            for name, value in vars(used.state).items():
                if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == 3:
                    np.testing.assert_array_equal(value[k], getattr(fresh.state, name)[k], err_msg=name)
        if left is not None:
            for name, value in vars(left).items():
                if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == 3:
                    np.testing.assert_array_equal(getattr(used.state, name)[1], value[1], err_msg=name)
            left = None
        used.step(actions), fresh.step(actions)


def test_metrics_accumulate_team_totals():
    config = WorldConfig(world_size=(8, 12), n_targets=(1, 3), n_agents=4, max_steps=9)
    world = SearchWorld(config, n_worlds=3, seed=1)
    world.reset()
    rng = np.random.default_rng(1)
    total_r, total_info = np.zeros(3), np.zeros(3)
    total_pairs, found = np.zeros(3, np.int64), np.zeros(3, np.int64)
    checked = 0
    for _ in range(40):
        n_targets = world.state.n_targets.copy()  # read before a reset redraws them
        tr = world.step(rng.integers(0, 5, size=(3, 4)))
        total_r += tr.result.reward.astype(np.float64).sum(axis=1)
        total_info += tr.result.info_collected.sum(axis=1)
        total_pairs += tr.result.comm_pairs
        found += tr.result.targets_found.sum(axis=1)
        for k in np.flatnonzero(tr.result.done):
            m = {name: v[k] for name, v in tr.metrics.items()}
            assert m["R"] == pytest.approx(total_r[k], rel=1e-5)
            assert m["M_bar"] * m["L"] == pytest.approx(total_info[k], rel=1e-9)
            assert m["F"] == total_pairs[k]
            assert m["found_fraction"] == found[k] / n_targets[k]
            total_r[k] = total_info[k] = total_pairs[k] = found[k] = 0
            checked += 1
    assert checked >= 3


@pytest.mark.parametrize("n_agents", [1, 7, 8, 13, 130])
def test_rewards_and_tallies_are_specs_sums_in_numpy_bit_for_bit(n_agents):
    """The compiled step adds each agent's reward terms in SPEC.md's order and sums the team's rewards and
    information as numpy sums a row (up to 8, to 128 and above: every branch of `numpy_sum`), so the rewards and
    the episode's tallies equal the same formula worked in numpy, bit for bit."""
    config = WorldConfig(world_size=(20, 20), n_targets=(2, 4), n_agents=n_agents, max_steps=12)
    state = allocate(config, 3)
    rng = np.random.default_rng(n_agents)
    reset_worlds(config, state, np.ones(3, bool), rng)
    for _ in range(10):
        before = state.copy()
        result = step(config, state, rng.integers(0, config.n_actions, size=(3, n_agents)), rng)
        reward64 = (config.step_reward + config.collision_reward * result.collided
                    + config.target_reward * result.targets_found + (config.xi / config.lam) * result.info_collected
                    + (config.tau / config.lam) * result.comm_gain)  # fmt: skip
        np.testing.assert_array_equal(result.reward, reward64.astype(np.float32))
        np.testing.assert_array_equal(state.ep_return, before.ep_return + reward64.sum(axis=1))
        np.testing.assert_array_equal(state.ep_info, before.ep_info + result.info_collected.sum(axis=1))
        np.testing.assert_array_equal(state.ep_collisions, before.ep_collisions + result.collided.sum(axis=1))
        np.testing.assert_array_equal(state.ep_comm_pairs, before.ep_comm_pairs + result.comm_pairs)
        np.testing.assert_array_equal(state.t, before.t + 1)
        np.testing.assert_array_equal(result.terminated, state.n_found == state.n_targets)
        np.testing.assert_array_equal(result.truncated, (state.t >= config.max_steps) & ~result.terminated)
    assert (state.ep_return != 0).all()


def test_numpy_sum_is_numpys_sum_of_a_row_at_every_length():
    rng = np.random.default_rng(0)
    for count in range(1_100):
        values = rng.normal(size=count + 5) * 10.0 ** rng.integers(-6, 6, size=count + 5)
        assert numpy_sum(values[3 : 3 + count]) == values[3 : 3 + count].sum(), count


@pytest.mark.parametrize(
    "actions, message",
    [
        (np.zeros((2, 3), np.int64), "shape"),
        (np.zeros((2, 4), np.float32), "dtype"),
        (np.zeros((2, 4), np.bool_), "dtype"),
        (np.full((2, 4), 5), "allowed"),
        (np.full((2, 4), -1), "allowed"),
        (np.full((2, 4), 200, np.uint8), "allowed"),
        (np.full((2, 4), -1, np.int8), "allowed"),
    ],
)
def test_bad_actions_are_rejected_before_any_work(actions, message):
    config = WorldConfig(world_size=(10, 10), n_agents=4)
    world = SearchWorld(config, n_worlds=2, seed=0)
    world.reset()
    before = world.state.copy()
    with pytest.raises(ValueError, match=message):
        check_actions(config, world.state, actions)
    with pytest.raises(ValueError, match=message):
        world.step(actions)
    np.testing.assert_array_equal(world.state.pos, before.pos)
    assert (world.state.t == before.t).all()


def test_bench_json_rows(capsys):
    assert bench_main(["memory", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert rows and {"case", "engine", "peak_rss_mb"} <= rows[0].keys()


SHARES = ("world_share", "acting_share", "labels_share", "buffer_share", "update_share")


@pytest.mark.slow  # the second of two bench train tests: the teacher-term one checks every share in the default run
def test_bench_train_reports_fps_and_the_shares_of_the_wall_time(capsys):
    assert bench_main(["train", "--updates", "1", "--threads", "1", "--network", "small", "--json"]) == 0
    (row,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert row["agent_steps_per_s"] > 0 and row["labels_share"] == 0 and row["device"].startswith("cpu")
    assert all(0 < row[share] < 1 for share in SHARES if share != "labels_share")
    assert sum(row[share] for share in SHARES) <= 1.0001  # parts of one wall time; SB3's bookkeeping is the rest
    assert row["slots"] == 16 * 8 and row["batch_size"] == 1024


@pytest.mark.slow  # a benchmark's second recipe
def test_bench_train_times_a_recipe_with_the_teacher_term(capsys):
    assert bench_main(["train", "--updates", "1", "--threads", "1", "--experiment", "term/b", "--json"]) == 0
    (row,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert row["case"] == "term_b_cpu_threads1" and row["agent_steps_per_s"] > 0
    assert all(0 < row[share] < 1 for share in SHARES)  # the world, acting, the labels, the buffer, the update
    assert sum(row[share] for share in SHARES) <= 1.0001  # parts of one wall time; SB3's bookkeeping is the rest
    # The raw bound of the same run: the network alone, acting and updating, in plain torch
    raw = 1 / (1 / row["raw_acting_agent_steps_per_s"] + 1 / row["raw_update_agent_steps_per_s"])
    assert row["raw_bound_agent_steps_per_s"] == pytest.approx(raw, rel=1e-3)
    # The ratio is of the unrounded rates, rounded to 3 places: the printed (rounded) rates give it to within 1e-3
    ratio = row["agent_steps_per_s"] / row["raw_bound_agent_steps_per_s"]
    assert row["ratio_to_raw_bound"] == pytest.approx(ratio, abs=1e-3)
    with pytest.raises(SystemExit):
        bench_main(["train", "--experiment", "nothing"])
    assert "--experiment=nothing is not allowed: one of" in capsys.readouterr().err


def test_the_raw_bound_between_updates_leaves_the_recipe_as_it_would_train_alone():
    """bench train measures its raw bound after each update, on the recipe's own policy: the parameters, torch's
    random state and numpy's global one are put back, so the recipe's later rollouts and updates are those of a run
    without it."""
    from hydra import compose, initialize_config_dir

    import searchrl.train.app  # noqa: F401  (registers the training schemas)
    from searchrl.bench.train import _then_bound
    from searchrl.shared_schema import CONF_DIR
    from searchrl.train.build import make_algorithm, make_vec_env
    from searchrl.train.plan import make_plan

    def trained(bounded: bool) -> list[torch.Tensor]:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            cfg = compose(config_name="train", overrides=["+model=b", "network=small", "threads=1", "env.n_worlds=2",
                                                          "env.world.n_agents=4", "env.world.world_size=[12,12]",
                                                          "algo.n_steps=8", "algo.batch_size=32"])  # fmt: skip
        torch.manual_seed(0)
        plan = make_plan(cfg)
        model = make_algorithm(plan, make_vec_env(plan, seed=0))
        seconds = [0.0], [0.0], [0.0]
        if bounded:
            model.train = _then_bound(model.train, model, lambda: None, *seconds)
        model.learn(3 * plan.rollout)
        assert (seconds[0][0] > 0) == bounded
        return [parameter.detach().clone() for parameter in model.policy.parameters()]

    for alone, bounded in zip(trained(False), trained(True), strict=True):
        assert torch.equal(alone, bounded)


def test_the_raw_bound_runs_a_critic_s_own_extractor_as_the_recipe_does():
    """A policy whose critic has its own extractor (`critic=true_state`) pays for it in every forward; the raw bound
    is of the same network, so it runs the critic's extractor as often as the actor's, acting and updating."""
    from hydra import compose, initialize_config_dir

    import searchrl.train.app  # noqa: F401  (registers the training schemas)
    from searchrl.bench.train import raw_acting_seconds, raw_update_seconds
    from searchrl.shared_schema import CONF_DIR
    from searchrl.train.build import make_algorithm, make_vec_env
    from searchrl.train.plan import make_plan

    overrides = ["+model=b", "network=small", "critic=true_state", "threads=1", "env.n_worlds=2",
                 "env.world.n_agents=4", "env.world.world_size=[12,12]", "algo.n_steps=8",
                 "algo.batch_size=32"]  # fmt: skip
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        plan = make_plan(compose(config_name="train", overrides=overrides))
    model = make_algorithm(plan, make_vec_env(plan, seed=0))
    model.learn(plan.rollout)
    policy = model.policy
    assert policy.vf_features_extractor is not policy.pi_features_extractor
    calls = {"actor": 0, "critic": 0}
    for name, extractor in (("actor", policy.pi_features_extractor), ("critic", policy.vf_features_extractor)):
        extractor.register_forward_hook(lambda *_, name=name: calls.__setitem__(name, calls[name] + 1))
    for raw in (raw_acting_seconds, raw_update_seconds):
        raw(model)
        assert calls["critic"] == calls["actor"] > 0, raw.__name__
        calls.update(actor=0, critic=0)


def test_bench_train_takes_the_training_app_s_overrides_and_names_the_case_by_them(capsys):
    """`bench train ... KEY=VALUE`: the app's overrides on the recipe (a critic, a network, a smaller world) are what
    is timed, the case's name carries them, and one that does not compose is refused in one line before any work."""
    tiny = ["env.n_worlds=2", "env.world.n_agents=4", "env.world.world_size=[12,12]", "algo.n_steps=8",
            "algo.batch_size=32", "critic=true_state"]  # fmt: skip
    args = ["train", "--network", "small", "--updates", "1", "--threads", "1", "--json", *tiny]
    assert bench_main(args) == 0
    (row,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert row["slots"] == 2 * 4 and row["batch_size"] == 32 and row["raw_bound_agent_steps_per_s"] > 0
    assert row["case"].startswith("recurrent_ppo_small_model_b_K2_N4+env.n_worlds=2+")
    assert row["case"].endswith("+critic=true_state_cpu_threads1")
    for bad, named in (("critic=nothing", "critic=nothing is not allowed: conf/critic/ has no 'nothing'"),
                       ("network.extractr=x", "network.extractr=x is not allowed: no such setting")):  # fmt: skip
        with pytest.raises(SystemExit):
            bench_main(["train", "--network", "small", "--updates", "1", bad])
        assert capsys.readouterr().err.strip().splitlines()[-1].startswith(f"python -m searchrl.bench: error: {named}")


def test_bench_train_takes_a_machine_and_refuses_a_missing_device_in_one_line(capsys):
    with pytest.raises(SystemExit):  # machine=gpu asks for cuda, which this machine lacks (CI has no GPU)
        bench_main(["train", "--machine", "gpu"] if not torch.cuda.is_available() else ["train", "--device", "cuda:99"])
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("python -m searchrl.bench: error: device=") and "not allowed" in err[-1]


def test_bench_eval_counts_the_worlds_steps_against_the_episodes(capsys):
    """`bench eval` on named cells: the episodes' steps are the cells' Σ L, and the worlds stepped more (a world
    whose episode ended steps with the batch until the last one ends)."""
    from searchrl.bench.evaluate import GRID
    from searchrl.controllers.factory import heuristic_factory
    from searchrl.evaluate.runner import run_cell

    assert bench_main(["eval", "--controller", "random", "--maps", "2", "--repeats", "3", "--cells", "n20_N2,n20_N32",
                       "--json"]) == 0  # fmt: skip
    (row,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    factory = heuristic_factory("random")
    lengths = sum(int(run_cell(factory, WorldConfig(), GRID[i], i, 2, 3, 7_000_000, needs_observation=False).L.sum())
                  for i in (1, 5))  # fmt: skip
    assert row["case"] == "random_n20_N2+n20_N32_2maps_3repeats" and row["episode_steps"] == lengths
    assert lengths < row["world_steps"] and row["busy_share"] == round(lengths / row["world_steps"], 4)


def test_bench_rejects_bad_arguments(capsys):
    with pytest.raises(SystemExit):
        bench_main(["world", "--seconds", "0"])
    assert "--seconds=0.0 is not allowed" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench_main(["eval", "--cells", "n20_N2,n21_N1"])
    assert "--cells=n20_N2,n21_N1 is not allowed: a comma-separated list of n20_N1, n20_N2," in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench_main(["eval", "--repeats", "0"])
    assert "--repeats=0 is not allowed: 1 <= repeats <= 100" in capsys.readouterr().err


def test_belief_age_dims_what_an_agent_saw_long_ago_and_only_that():
    """With belief_age the belief channels of a cell the agent has not seen for s steps show exp(−belief_age·ρ·s)
    of its belief (ρ = N·ΣΓ / free cells); cells inside Φ show it whole; without belief_age nothing changes."""
    from searchrl.world.footprint import GAMMA

    base = WorldConfig(world_size=(30, 30), n_targets=(1, 1), n_agents=2, max_steps=50)
    aged = WorldConfig(**{**base.__dict__, "belief_age": 1.0})
    plain, old = SearchWorld(base, n_worlds=1, seed=3), SearchWorld(aged, n_worlds=1, seed=3)
    plain.reset(), old.reset()
    actions = np.full((1, 2), 1)  # the same moves in both worlds, so the same beliefs
    for _ in range(6):
        tr_plain, tr_old = plain.step(actions), old.step(actions)
    np.testing.assert_array_equal(tr_plain.maps[:, :, :3], tr_old.maps[:, :, :3])
    rate = 1.0 * 2 * GAMMA.sum() / 30**2
    half, phi = base.fov // 2, base.explicit_area // 2
    seen_at = old.state.belief_time[0, 0]
    r, c = old.state.pos[0, 0] + old.state.halo
    stale = 6 - seen_at[r - half : r + half + 1, c - half : c + half + 1]  # (fov, fov) steps since seen
    assert stale[half - phi : half + phi + 1, half - phi : half + phi + 1].max() == 0
    assert stale.max() == 6  # cells of the field of view it never saw date from the reset
    expected = tr_plain.maps[0, 0, 3:] * np.exp(-rate * stale)
    np.testing.assert_allclose(tr_old.maps[0, 0, 3:], expected, rtol=1e-5)
    assert (tr_old.maps[0, 0, 3:] < tr_plain.maps[0, 0, 3:]).any()


def test_belief_age_channel_shows_the_factor_beside_an_unscaled_belief():
    """With belief_age_channel the same factor fills a sixth channel and the five others are those of a world
    without belief_age; the observation space says six channels."""
    from searchrl.envs.spaces import observation_space

    base = WorldConfig(world_size=(30, 30), n_targets=(1, 1), n_agents=2, max_steps=50)
    scaled = WorldConfig(**{**base.__dict__, "belief_age": 1.0})
    shown = WorldConfig(**{**scaled.__dict__, "belief_age_channel": True})
    assert observation_space(shown)["map"].shape == (6, 11, 11)
    assert observation_space(scaled)["map"].shape == (5, 11, 11)
    worlds = [SearchWorld(c, n_worlds=1, seed=3) for c in (base, scaled, shown)]
    for w in worlds:
        w.reset()
    actions = np.full((1, 2), 1)
    for _ in range(6):
        plain, old, chan = (w.step(actions) for w in worlds)
    np.testing.assert_array_equal(chan.maps[:, :, :5], plain.maps)
    fresh = chan.maps[0, 0, 5]
    assert fresh.min() < 1.0 and fresh.max() == 1.0  # Φ was seen this step; the rest of the view earlier
    np.testing.assert_allclose(old.maps[0, 0, 3:], plain.maps[0, 0, 3:] * fresh, rtol=1e-6)


@pytest.mark.parametrize("n", [12, 20])
def test_k_per_n_senses_each_world_with_its_own_side(n):
    """k = k + k_per_n·n: with k = 0, k_per_n = 1 one footprint scales the cell under a lone agent by 1 − λ·n·Γ."""
    from searchrl.world.footprint import GAMMA

    config = WorldConfig(world_size=(n, n), n_agents=1, n_targets=(1, 1), k=0.0, k_per_n=1.0)
    world = SearchWorld(config, n_worlds=1, seed=0)
    world.reset()
    r, c = world.state.pos[0, 0] + world.state.halo
    before = float(world.state.p[0, r, c])
    world.step(np.zeros((1, 1), np.int64))  # stay
    factor = 1 - config.lam * n * float(GAMMA[2, 2])
    assert world.state.p[0, r, c] == pytest.approx(before * factor, rel=1e-6)
    np.testing.assert_allclose(config.sensing_rate(np.array([20, 40])), [0.02, 0.04])


def test_the_kernels_view_of_the_state_follows_a_rebound_field():
    """`WorldState.arrays()` is built once and kept while the fields stay the same arrays (in-place updates such as
    `state.t += 1` keep it); rebinding a field builds a new one, so no kernel reads a stale array."""
    config = WorldConfig(world_size=(10, 10), n_targets=(1, 1), n_agents=2)
    state = allocate(config, 1)
    reset_worlds(config, state, np.ones(1, bool), np.random.default_rng(0))
    view = state.arrays()
    state.t += 1
    assert state.arrays() is view
    state.pos = state.pos[:, ::-1].copy()  # a new array: each agent's (col, row)
    assert state.arrays() is not view
    _, vector = observe(config, state)
    np.testing.assert_array_equal(vector[0, :, :2], (state.pos[0, :, ::-1] / 10).astype(np.float32))
    assert state.copy().arrays() is not state.arrays()
    twin = pickle.loads(pickle.dumps(copy.deepcopy(state)))  # the view is left behind and rebuilt
    np.testing.assert_array_equal(observe(config, twin)[1], vector)
