"""Networks, critics and observation parts by name: the coarse views against a numpy reference, an actor that never
reads the critic's true state, a whole-map branch that starts as the clone, and a run with both that evaluates,
renders, resumes, loads in plain SB3 and acts in the PettingZoo env without any true state."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from searchrl.envs.parts import make_part, make_parts
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.world.coarse import OwnMap, TrueState
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.engine import SearchWorld

WORLD = WorldConfig(n_agents=3, world_size=(12, 20), n_targets=(2, 4), n_distributions=(4, 8), max_steps=9)


def _pooled(grid_map: np.ndarray, n: int, grid: int, mean: bool = True) -> np.ndarray:
    """(n, n) -> (grid, grid): the mean (or sum) of the cells falling in each coarse cell, by plain indexing."""
    out, count = np.zeros((grid, grid)), np.zeros((grid, grid))
    for r in range(n):
        for c in range(n):
            out[r * grid // n, c * grid // n] += grid_map[r, c]
            count[r * grid // n, c * grid // n] += 1
    return np.where(count > 0, out / np.maximum(count, 1), 0) if mean else out


def _reference(world: SearchWorld, k: int, grid: int) -> tuple[np.ndarray, np.ndarray]:
    """own_map and true_state of world k, agent by agent, from the state's arrays."""
    s, h = world.state, world.state.halo
    n, agents = int(s.size[k]), s.n_agents
    inner = (slice(h, h + n), slice(h, h + n))
    belief = s.belief[k][(slice(None), slice(None), *inner)].astype(np.float64)  # (N, 2, n, n)
    scale = s.obs_scale[k].astype(np.float64)
    own = np.zeros((agents, 3, grid, grid))
    true = np.zeros((agents, 6, grid, grid))
    team = belief.min(axis=0)
    targets = np.zeros((n, n))
    for j in np.flatnonzero(s.target_valid[k] & ~s.target_found[k]):
        targets[tuple(s.target_pos[k, j])] += 1
    everyone = np.zeros((n, n))
    for i in range(agents):
        everyone[tuple(s.pos[k, i])] += 1 / agents
    for i in range(agents):
        here = np.zeros((grid, grid))
        here[s.pos[k, i, 0] * grid // n, s.pos[k, i, 1] * grid // n] = 1
        own[i] = [_pooled(belief[i, 0], n, grid) * scale[0], _pooled(belief[i, 1], n, grid) * scale[1], here]
        left = max(0.0, 1 - s.t[k] / world.config.max_steps)
        true[i] = [_pooled(team[0], n, grid) * scale[0], _pooled(team[1], n, grid) * scale[1],
                   _pooled(targets, n, grid, mean=False), _pooled(everyone, n, grid, mean=False), here,
                   np.full((grid, grid), left)]  # fmt: skip
    return own, true


@pytest.mark.parametrize("grid", [4, 7, 16])
def test_coarse_views_match_the_reference_through_steps_and_resets(grid):
    parts = make_parts([("own_map", {"grid": grid}), ("true_state", {"grid": grid})])
    world = SearchWorld(WORLD, 3, seed=1, parts=parts)
    world.reset()
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(20):  # max_steps 9: every world ends and restarts at least once
        before = {k: _reference(world, k, grid) for k in range(3)}
        tr = world.step(rng.integers(0, 5, (3, 3)))
        for k in range(3):
            own, true = _reference(world, k, grid)
            np.testing.assert_allclose(tr.parts["own_map"][k], own, rtol=1e-5, atol=1e-7)
            np.testing.assert_allclose(tr.parts["true_state"][k], true, rtol=1e-5, atol=1e-7)
            if tr.result.done[k]:  # the final view is the last step's, taken before the reset
                ended += 1
                assert tr.final_parts["true_state"][k, :, 5].max() == 0.0  # no time left
                assert not np.array_equal(tr.final_parts["own_map"][k], before[k][0])  # moved on from the step before
            np.testing.assert_array_equal(tr.parts["true_state"][k, :, 5], np.float32(1 - world.state.t[k] / 9))
    assert ended >= 3


def test_parts_reach_the_vec_env_and_its_terminal_observations():
    parts = make_parts([("own_map", {"grid": 8}), ("true_state", {"grid": 8})])
    env = SearchVecEnv(WORLD, 2, seed=0, parts=parts)
    obs = env.reset()
    assert set(obs) == {"map", "vector", "own_map", "true_state"}
    assert obs["own_map"].shape == (6, 3, 8, 8) and obs["true_state"].shape == (6, 6, 8, 8)
    assert env.observation_space["true_state"].contains(obs["true_state"][0])
    for _ in range(9):
        obs, _, dones, infos = env.step(np.zeros(6, np.int64))
    assert dones.all() and set(infos[0]["terminal_observation"]) == set(obs)
    assert (obs["true_state"][:, 5] == 1).all() and (infos[0]["terminal_observation"]["true_state"][5] == 0).all()


def test_unknown_names_are_refused_with_the_nearest():
    with pytest.raises(ConfigError, match=r"observation part='own_mapp' is not allowed: .* .did you mean 'own_map'"):
        make_part("own_mapp")
    from searchrl.policies.networks import CRITICS, NETWORKS

    with pytest.raises(ConfigError, match=r"extractor='search_cn' is not allowed: .* .did you mean 'search_cnn'"):
        NETWORKS.lookup("search_cn")
    assert set(CRITICS) >= {"shared", "true_state"} and isinstance(make_part("true_state"), TrueState)
    assert isinstance(make_part("own_map", grid=5), OwnMap)


def _plan(*overrides: str):
    from searchrl.train.plan import make_plan
    from tests.test_train import TINY, _compose

    tiny = [o for o in TINY if "algo=a2c" not in overrides or not o.startswith("algo.batch_size")]  # PPO's only
    return make_plan(_compose(["+model=b", *tiny, *overrides]))


@pytest.mark.parametrize(("overrides", "message"), [
    (["network.extractor=own_map"], "network.extractor='own_map' is not allowed: .* .did you mean 'own_map_cnn'"),
    (["critic=true_state", "algo=a2c"], "critic.name='true_state' needs algo=recurrent_ppo"),
    (["critic=true_state", "critic.grid=3"], "critic.grid=3 is not allowed"),
    (["critic=true_state", "imitation=greedy_target"], "imitation.epochs=.* is not allowed: 0 with"),
])  # fmt: skip
def test_the_plan_refuses_what_cannot_be_built(overrides, message):
    with pytest.raises(ConfigError, match=message):
        _plan(*overrides)


def _model(*overrides: str):
    from searchrl.train.build import make_algorithm, make_vec_env

    plan = _plan(*overrides)
    return plan, make_algorithm(plan, make_vec_env(plan, seed=0))


def _obs(space, batch: int, seed: int) -> dict[str, torch.Tensor]:
    space.seed(seed)
    return {k: torch.as_tensor(np.stack([space[k].sample() for _ in range(batch)])) for k in space.spaces}


def test_the_actor_never_reads_the_true_state_the_critic_does():
    _, model = _model("critic=true_state")
    policy = model.policy
    obs = _obs(policy.observation_space, 6, 0)
    other = {**obs, "true_state": obs["true_state"] * 0 + 3.0}
    states = (torch.zeros(1, 6, policy.lstm_actor.hidden_size),) * 2
    starts = torch.ones(6)
    with torch.no_grad():
        dist = policy.get_distribution(obs, states, starts)[0].distribution.logits
        dist_other = policy.get_distribution(other, states, starts)[0].distribution.logits
        value, value_other = (policy.predict_values(o, states, starts) for o in (obs, other))
    torch.testing.assert_close(dist, dist_other, rtol=0, atol=0)
    assert not torch.allclose(value, value_other)  # the critic does read it
    from searchrl.policies.actor import Actor

    actor = Actor(policy, optimize=False)
    assert actor.keys == ("map", "vector") and actor.parts == ()
    # the true state's branch is the critic's alone, fitted in the critic's warm-up
    from searchrl.imitation.teacher_term import value_parameters

    assert {id(p) for p in policy.vf_features_extractor.parameters()} <= {id(p) for p in value_parameters(policy)}


def test_a_whole_map_branch_starts_as_the_clone_it_is_initialised_from(tmp_path, monkeypatch):
    from searchrl.train import build
    from searchrl.train.build import init_weights
    from tests.test_train import TINY, _run

    source = _run(tmp_path / "source", ["+model=b", *TINY, "total_timesteps=256", "validation.every=0"])
    _, model = _model("network.extractor=own_map_cnn", "critic=true_state")
    fresh = init_weights(model, str(source), None)
    assert fresh == ["features_extractor.gate", "features_extractor.grid", "vf_features_extractor.grid"]
    from searchrl.policies.checkpoint import load_checkpoint

    clone = load_checkpoint(source).policy
    obs = _obs(model.policy.observation_space, 5, 1)
    states, starts = (torch.zeros(1, 5, clone.lstm_actor.hidden_size),) * 2, torch.ones(5)
    with torch.no_grad():
        ours = model.policy.get_distribution(obs, states, starts)[0].distribution.logits
        theirs = clone.get_distribution({"map": obs["map"], "vector": obs["vector"]}, states, starts)[0]
    torch.testing.assert_close(ours, theirs.distribution.logits)
    _, wider = _model("network.lstm_hidden_size=16")
    with pytest.raises(ValueError, match=r"does not fit .*: action_net.weight is \(5, 128\) there, \(5, 16\) here"):
        init_weights(wider, str(source), None)
    # a checkpoint without the policy's actor head (every other tensor fits) is refused, not half copied
    real = build.load_checkpoint

    def headless(*args, **kwargs):
        tensors = real(*args, **kwargs).policy.state_dict()
        kept = {k: v for k, v in tensors.items() if not k.startswith("action_net")}
        return SimpleNamespace(policy=SimpleNamespace(state_dict=lambda: kept))

    monkeypatch.setattr(build, "load_checkpoint", headless)
    _, same = _model()
    with pytest.raises(ValueError, match=r"does not fit .*: it has no actor head of this policy"):
        init_weights(same, str(source), None)


@pytest.mark.app
def test_a_run_with_a_whole_map_actor_and_a_true_state_critic_is_used_like_any_other(tmp_path, capsys):
    from sb3_contrib import RecurrentPPO

    from searchrl.envs.parallel_env import SearchParallelEnv
    from searchrl.policies.actor import sample_actions
    from searchrl.policies.checkpoint import load_actor
    from searchrl.render import main as render
    from searchrl.train.app import train
    from tests.test_evaluate import _evaluate
    from tests.test_train import TINY, _compose, _run

    run = tmp_path / "run"
    overrides = ["+model=b", *TINY, "network.extractor=own_map_cnn", "critic=true_state", "network.grid=6",
                 "critic.grid=5", "imitation.critic_warmup=2"]  # fmt: skip
    final = _run(run, overrides)
    saved = OmegaConf.load(run / "config.yaml")  # the record says what the critic saw
    assert saved.critic.name == "true_state" and saved.critic.grid == 5 and saved.network.extractor == "own_map_cnn"
    plain = RecurrentPPO.load(final)  # plain SB3 opens it (our classes are importable)
    assert set(plain.observation_space.spaces) == {"map", "vector", "own_map", "true_state"}
    frame = _evaluate(tmp_path / "eval", f"checkpoint={final}")
    assert len(frame) == 18 and frame.found_fraction.between(0, 1).all()
    assert render(["--checkpoint", str(final), "--n", "20", "--out", str(tmp_path / "e.gif")]) == 0
    resumed = [f"resume={run}", "total_timesteps=2304"]
    train(_compose(resumed), run / "resumed", resumed)
    assert RecurrentPPO.load(run / "model.zip").num_timesteps == 2304
    world = WorldConfig.from_dict({**OmegaConf.to_container(saved.env.world), "world_size": 16})
    actor = load_actor(final, world)
    assert [p.key for p in actor.parts] == ["own_map"]
    env = SearchParallelEnv(world, parts=actor.parts)  # the actor's parts; no true state anywhere
    obs, _ = env.reset(seed=3)
    assert "true_state" not in obs["agent_0"]
    state = actor.initial_state(world.n_agents)
    for _ in range(5):
        rows = [obs[a] for a in env.agents]
        logits, state = actor.logits(np.stack([o["map"] for o in rows]), np.stack([o["vector"] for o in rows]),
                                     state, {"own_map": np.stack([o["own_map"] for o in rows])})  # fmt: skip
        actions = sample_actions(logits, None)
        obs, *_ = env.step(dict(zip(env.agents, actions.tolist(), strict=True)))
    assert Path(tmp_path / "e.gif").stat().st_size > 0
