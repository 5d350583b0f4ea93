"""Imitation warm start: demonstrations are the teacher's, deterministic per seed, and cloning fits them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from sb3_contrib import RecurrentPPO
from stable_baselines3 import PPO

from searchrl.controllers.registry import make_teacher, teacher_settings
from searchrl.controllers.surfing import InformationSurfing
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.imitation.clone import _evaluate, clone, collect, discounted_returns, lr_factor
from searchrl.imitation.teacher_term import value_parameters
from searchrl.policies.extractor import SearchCNN
from searchrl.policies.recurrent import SequenceLstmPolicy
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

WORLD = replace(WorldConfig(), world_size=(12, 16), n_targets=(2, 3), n_distributions=(4, 6), n_agents=3,
                max_steps=24)  # fmt: skip
EXTRACTOR = {"conv_channels": [8, 8, 8], "vector_size": 8, "fc_sizes": [32]}


def _tiny_model(algo: type[PPO] | type[RecurrentPPO]) -> PPO | RecurrentPPO:
    """A small network on WORLD, with the policy class a training builds for `algo`."""
    env = SearchVecEnv(WORLD, n_worlds=1, seed=0)
    kwargs = {"features_extractor_class": SearchCNN, "features_extractor_kwargs": EXTRACTOR, "net_arch": []}
    if algo is RecurrentPPO:
        kwargs["lstm_hidden_size"] = 32
    policy = SequenceLstmPolicy if algo is RecurrentPPO else "MultiInputPolicy"
    return algo(policy, env, n_steps=8, batch_size=24, policy_kwargs=kwargs, seed=0)


def _replay(config: WorldConfig, n_worlds: int, teacher: str, teacher_seed: int, world_seed: list[int],
            teacher_args: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[float]]:  # fmt: skip
    """A fresh `teacher` playing `n_worlds` worlds of `config` seeded as collect seeds round `world_seed` = (seed, j,
    e), reset where an episode ends: (moves, rewards, dones) as (slots, T), and each ended episode's found fraction."""
    world, rule = (
        SearchWorld(config, n_worlds),
        make_teacher(teacher_settings(teacher, teacher_args), config, teacher_seed),
    )
    maps, vector = world.reset(seed=int(np.random.SeedSequence(world_seed).generate_state(1)[0]))
    rule.reset(world.state, np.ones(n_worlds, bool))
    moves, rewards, dones, found = [], [], [], []
    for _ in range(config.max_steps):
        moves.append(rule.act(world.state, maps, vector).reshape(-1))
        tr = world.step(moves[-1].reshape(n_worlds, -1))
        done = tr.result.done
        rewards.append(tr.result.reward.reshape(-1))
        dones.append(np.repeat(done, config.n_agents).astype(np.float32))
        if done.any():
            rule.reset(world.state, done)
            found += tr.metrics["found_fraction"][done].tolist()
        maps, vector = tr.maps, tr.vector
    return np.stack(moves, 1), np.stack(rewards, 1), np.stack(dones, 1), found


def test_discounted_returns_stop_at_episode_ends():
    rewards = np.array([[1.0, 2.0, 4.0, 8.0]], np.float32)
    dones = np.array([[0.0, 1.0, 0.0, 0.0]], np.float32)
    expected = [1.0 + 0.5 * 2.0, 2.0, 4.0 + 0.5 * 8.0, 8.0]  # the sequence end is cut: no bootstrap
    np.testing.assert_allclose(discounted_returns(rewards, dones, 0.5)[0], expected)


def test_discounted_returns_accumulate_in_the_rewards_dtype():
    """float32 rewards give the float32 recursion's returns bit for bit (a float64 running sum rounds otherwise)."""
    rng = np.random.default_rng(0)
    rewards, dones = rng.random((3, 50), np.float32), (rng.random((3, 50)) < 0.1).astype(np.float32)
    expected = np.zeros_like(rewards)
    for s in range(3):
        running = np.float32(0.0)
        for t in range(49, -1, -1):
            running = rewards[s, t] + 0.9 * running * (np.float32(1.0) - dones[s, t])
            expected[s, t] = running
    returns = discounted_returns(rewards, dones, 0.9)
    assert returns.dtype == np.float32
    np.testing.assert_array_equal(returns, expected)


def test_demonstrations_are_the_teachers_and_the_same_per_seed():
    demos = collect(
        [(WORLD, 2), (replace(WORLD, n_agents=5), 1)], teacher_settings("surfing"), episodes=2, gamma=0.9, seed=3
    )
    assert demos.maps.shape == (2 * (2 * 3 + 5), 24, 5, 11, 11) and demos.actions.shape == (22, 24)
    assert demos.starts[:, 0].sum() == 0  # every sequence starts a fresh episode: the LSTM starts from zeros
    assert (demos.maps.dtype, demos.vector.dtype, demos.actions.dtype) == (np.float16, np.float32, np.int64)
    again = collect(
        [(WORLD, 2), (replace(WORLD, n_agents=5), 1)], teacher_settings("surfing"), episodes=2, gamma=0.9, seed=3
    )
    for name in ("maps", "vector", "actions", "starts", "returns"):
        np.testing.assert_array_equal(getattr(demos, name), getattr(again, name))
    other = collect([(WORLD, 2)], teacher_settings("surfing"), episodes=1, gamma=0.9, seed=4)
    assert not np.array_equal(other.maps, demos.maps[: len(other)])
    # Replaying round 0 of group 0 with a fresh teacher gives the recorded first step.
    world = SearchWorld(WORLD, 2)
    maps, vector = world.reset(seed=int(np.random.SeedSequence([3, 0, 0]).generate_state(1)[0]))
    teacher = InformationSurfing(WORLD, seed=3)
    np.testing.assert_array_equal(teacher.act(world.state, maps, vector).reshape(-1), demos.actions[:6, 0])
    np.testing.assert_array_equal(maps.reshape(6, 5, 11, 11).astype(np.float16), demos.maps[:6, 0])


def test_demonstrations_are_played_in_the_scenario_given():
    from searchrl.world.obstacles import IidObstacles
    from searchrl.world.scenario import Scenario

    walls = Scenario(IidObstacles(0.3, connected=True))
    demos = collect([(WORLD, 2)], teacher_settings("surfing"), episodes=1, gamma=0.9, seed=3, scenario=walls)
    world, open_grid = SearchWorld(WORLD, 2, scenario=walls), SearchWorld(WORLD, 2)
    seed = int(np.random.SeedSequence([3, 0, 0]).generate_state(1)[0])
    (maps, _), (open_maps, _) = world.reset(seed=seed), open_grid.reset(seed=seed)
    np.testing.assert_array_equal(maps.reshape(6, 5, 11, 11).astype(np.float16), demos.maps[:, 0])
    assert not np.array_equal(open_maps.reshape(6, 5, 11, 11).astype(np.float16), demos.maps[:, 0])


def test_a_later_groups_demonstration_is_its_teachers_whole_episode_replayed():
    """Group j's demonstration is its teacher (seeded seed + j) playing its worlds (seeded (seed, j, 0)) step by step,
    reset where an episode ends: the moves, the episode starts and the returns of its rewards are the replay's, and
    the found fraction is the mean over both groups' ended episodes."""
    groups = [(WORLD, 2), (replace(WORLD, n_agents=5), 1)]
    demos = collect(groups, teacher_settings("surfing"), episodes=1, gamma=0.9, seed=3)
    moves, rewards, dones, found = _replay(*groups[1], "surfing", 3 + 1, [3, 1, 0])
    np.testing.assert_array_equal(moves, demos.actions[6:])
    np.testing.assert_array_equal(discounted_returns(rewards, dones, 0.9), demos.returns[6:])
    np.testing.assert_array_equal(np.concatenate([np.zeros((5, 1)), dones[:, :-1]], 1), demos.starts[6:])
    assert demos.starts.dtype == demos.returns.dtype == np.float32
    found_first = _replay(*groups[0], "surfing", 3, [3, 0, 0])[3]
    assert found and demos.found_fraction == pytest.approx(np.mean(found_first + found), abs=1e-12)


def test_an_episode_that_ends_on_a_rounds_second_last_step_marks_a_start_on_its_last():
    """World 0 of this round finds its targets at step 38 of 0-39 and starts anew at 39, where its agents' LSTMs
    reset."""
    small = replace(WORLD, world_size=(12, 12), n_targets=(1, 2), max_steps=40)
    demos = collect([(small, 2)], teacher_settings("surfing"), episodes=1, gamma=0.9, seed=0)
    assert demos.starts[:3, -1].tolist() == [1.0] * 3 and not demos.starts[3:, -1].any()


def test_each_round_starts_its_teacher_afresh():
    """Round 1 of a teacher with memory (B's teacher: target-greedy with reach 2 keeps per-world reach weights) is
    what a new teacher plays in that round's world: collect resets it with a boolean mask of all worlds."""
    demos = collect([(WORLD, 2)], teacher_settings("greedy_target", {"reach": 2}), episodes=2, gamma=0.9, seed=3)
    moves = _replay(WORLD, 2, "greedy_target", 3, [3, 0, 1], {"reach": 2})[0]
    np.testing.assert_array_equal(moves, demos.actions[6:])


def test_a_teacher_is_given_the_observations_recorded(monkeypatch):
    """A registered teacher may act on the agents' observations (a learned or map-reading rule): each step it is given
    the maps and vectors the demonstration records."""
    from searchrl.controllers import registry
    from searchrl.controllers.base import ControllerConfig, RandomWalk

    seen = []

    class Spy(RandomWalk):
        def act(self, state, maps, vector, active=None):
            seen.append((maps.copy(), vector.copy()))
            return super().act(state, maps, vector, active)

    monkeypatch.setitem(registry.HEURISTICS, "spy", registry.Heuristic(Spy, ControllerConfig, "spy"))
    demos = collect([(WORLD, 2)], teacher_settings("spy"), episodes=1, gamma=0.9, seed=3)
    assert len(seen) == WORLD.max_steps
    maps = np.stack([m.reshape(6, 5, 11, 11) for m, _ in seen], 1).astype(np.float16)
    np.testing.assert_array_equal(maps, demos.maps)
    np.testing.assert_array_equal(np.stack([v.reshape(6, 3) for _, v in seen], 1), demos.vector)


def test_unknown_teacher_is_named():
    with pytest.raises(ValueError, match=r"imitation\.teacher='planner'"):
        collect([(WORLD, 1)], teacher_settings("planner"), episodes=1, gamma=0.9, seed=0)


def test_teacher_args_build_the_teacher_and_bad_ones_are_named():
    args = {"horizon": 1, "contested": 0.5}
    demos = collect([(WORLD, 2)], teacher_settings("greedy", args), episodes=1, gamma=0.9, seed=3)
    world = SearchWorld(WORLD, 2)
    maps, vector = world.reset(seed=int(np.random.SeedSequence([3, 0, 0]).generate_state(1)[0]))
    teacher = make_teacher(teacher_settings("greedy", args), WORLD, 3)
    assert (teacher.horizon, teacher.contested) == (1, 0.5)
    np.testing.assert_array_equal(teacher.act(world.state, maps, vector).reshape(-1), demos.actions[:6, 0])
    for bad, message in [({"sweep": 2}, "sweep"), ({"horizon": 0}, "horizon=0"), ({"seed": 1}, "seed")]:
        with pytest.raises(ValueError, match=rf"imitation\.teacher_args.*{message}"):
            make_teacher(teacher_settings("greedy", bad), WORLD, 0)


@pytest.mark.parametrize("algo", [RecurrentPPO, PPO])
def test_cloning_fits_the_teacher(algo):
    """A few epochs on the demonstrations raise the accuracy on the teacher's actions well above chance (1/5)."""
    torch.manual_seed(0)
    demos = collect([(WORLD, 4)], teacher_settings("surfing"), episodes=2, gamma=0.9, seed=0)
    model = _tiny_model(algo)
    history = clone(model.policy, demos, epochs=12, value_epochs=4, batch_sequences=4, learning_rate=1e-3, seed=0)
    assert [r["phase"] for r in history] == ["policy"] * 12 + ["value"] * 4
    assert history[11]["imitation_loss"] < history[0]["imitation_loss"]
    assert history[11]["accuracy"] > 0.5  # the teacher's most common action is 0.41 of these
    assert history[-1]["value_loss"] < history[12]["value_loss"] < history[11]["value_loss"]
    assert history[-1]["accuracy"] == pytest.approx(history[12]["accuracy"], abs=1e-6)  # the actor is left alone
    assert {r["learning_rate"] for r in history} == {1e-3}  # the default schedule is constant


def test_an_epochs_metrics_are_the_means_over_its_minibatches(monkeypatch):
    """At learning rate 0 nothing moves, so an epoch's imitation loss, value loss and accuracy (means over equal
    minibatches) are the policy's over all the demonstrations, phase by phase; each minibatch's gradient is clipped
    at norm 10 over the phase's parameters."""
    demos = collect([(WORLD, 4)], teacher_settings("surfing"), episodes=1, gamma=0.9, seed=0)
    model = _tiny_model(PPO)
    assert len(demos) == 12  # 4 minibatches of 3 sequences
    clips, clip = [], torch.nn.utils.clip_grad_norm_
    spy = lambda parameters, norm: clips.append((len(parameters), norm)) or clip(parameters, norm)  # noqa: E731
    monkeypatch.setattr(torch.nn.utils, "clip_grad_norm_", spy)
    rows = []
    history = clone(model.policy, demos, 1, 1, 3, 0.0, seed=0, on_epoch=rows.append)
    assert rows == history  # each row to the callback as its epoch ends
    value_only = len(value_parameters(model.policy))
    assert clips == [(len(list(model.policy.parameters())), 10.0)] * 4 + [(value_only, 10.0)] * 4
    dist, values, actions = _evaluate(model.policy, demos, np.arange(len(demos)))
    expected = {
        "imitation_loss": -dist.log_prob(actions).mean().item(),
        "value_loss": torch.nn.functional.mse_loss(values, torch.as_tensor(demos.returns).reshape(-1)).item(),
        "accuracy": (dist.distribution.probs.argmax(dim=1) == actions).float().mean().item(),
    }
    assert [(row["epoch"], row["phase"]) for row in history] == [(1, "policy"), (2, "value")]  # numbered from 1
    for row in history:
        assert {key: row[key] for key in expected} == pytest.approx(expected, rel=1e-5)


def test_linear_schedule_takes_each_phase_down_to_zero():
    """lr_schedule="linear": each phase starts at learning_rate and its last minibatch runs at learning_rate/steps;
    an unknown schedule is refused by name."""
    torch.manual_seed(0)
    demos = collect([(WORLD, 4)], teacher_settings("surfing"), episodes=1, gamma=0.9, seed=0)
    n = -(-len(demos) // 2)  # minibatches of 2 sequences per epoch
    model = _tiny_model(PPO)
    history = clone(model.policy, demos, 2, 1, 2, 2e-3, seed=0, lr_schedule="linear")  # not Adam's default 1e-3
    rates = [r["learning_rate"] for r in history]
    # the rate of each epoch's last step: policy 2 epochs (2n steps), value 1 epoch (n steps)
    assert rates == pytest.approx([2e-3 * (n + 1) / (2 * n), 2e-3 / (2 * n), 2e-3 / n])
    assert lr_factor("linear", 0, 4) == 1.0 and lr_factor("constant", 3, 4) == 1.0
    assert len(clone(model.policy, demos, 1, 0, 2, 1e-3, seed=0, lr_schedule="linear")) == 1  # no value phase
    with pytest.raises(ValueError, match=r"^imitation\.lr_schedule='cosine' is not allowed: one of constant, linear$"):
        lr_factor("cosine", 0, 4)


def test_linear_rate_reaches_zero_where_a_phase_ends():
    """1 − step/steps at step == steps (where LambdaLR leaves a phase after its last minibatch) is 0, one minibatch or
    many."""
    assert [lr_factor("linear", s, s) for s in (1, 2, 7)] == [0.0, 0.0, 0.0]
    assert lr_factor("linear", 0, 0) == 1.0  # a phase of 0 epochs: no division by zero


def test_clone_redraws_the_head_at_unit_gain_and_its_minibatch_order_follows_the_seed():
    """The action head is re-drawn orthogonal with gain 1 and zero bias before fitting (the docstring's reason: SB3's
    gain 0.01 starves the extractor); two clones from the same weights and seed end equal, another seed apart."""
    demos = collect([(WORLD, 4)], teacher_settings("surfing"), episodes=1, gamma=0.9, seed=0)
    model = _tiny_model(PPO)
    start = {k: v.clone() for k, v in model.policy.state_dict().items()}
    clone(model.policy, demos, 0, 0, 2, 1e-3, seed=0)  # no epochs: only the head's re-draw
    weight = model.policy.action_net.weight.detach()  # (5 actions, features): orthonormal rows at gain 1
    torch.testing.assert_close(weight @ weight.T, torch.eye(weight.shape[0]), atol=1e-5, rtol=0)
    assert not model.policy.action_net.bias.detach().any()

    def fitted(seed: int) -> list[torch.Tensor]:
        model.policy.load_state_dict(start)
        torch.manual_seed(0)  # the head's re-draw: the same in every call
        clone(model.policy, demos, 2, 0, 2, 1e-3, seed=seed)
        return [p.detach().clone() for p in model.policy.parameters()]

    same, again, other = fitted(0), fitted(0), fitted(1)
    assert all(torch.equal(a, b) for a, b in zip(same, again, strict=True))
    assert not all(torch.equal(a, b) for a, b in zip(same, other, strict=True))
