"""The teacher term during RL: SB3's update when off, online labels that are the teacher's, a term that pulls the
policy toward the teacher, a critic warm-up that leaves the policy alone, and the training app around them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
import torch
from sb3_contrib import RecurrentPPO
from stable_baselines3.common.utils import set_random_seed

from searchrl.controllers.registry import make_teacher, teacher_settings
from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.imitation.teacher_labels import TeacherLabels
from searchrl.imitation.teacher_term import TeacherRecurrentPPO
from searchrl.policies.extractor import SearchCNN
from searchrl.train.app import train
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from tests.test_train import TINY, _compose, _run

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

WORLD = replace(WorldConfig(), world_size=(12, 16), n_targets=(2, 3), n_distributions=(4, 6), n_agents=3,
                max_steps=24)  # fmt: skip
EXTRACTOR = {"conv_channels": [8, 8, 8], "vector_size": 8, "fc_sizes": [32]}
TEACHER = ("greedy", {"horizon": 1})


def _model(cls, env, **kwargs):
    recurrent = issubclass(cls, RecurrentPPO)
    policy_kwargs = {"features_extractor_class": SearchCNN, "features_extractor_kwargs": EXTRACTOR, "net_arch": []}
    if recurrent:
        policy_kwargs["lstm_hidden_size"] = 16
    policy = "MultiInputLstmPolicy" if recurrent else "MultiInputPolicy"
    settings = {"n_steps": 8, "batch_size": 48, "n_epochs": 2, "seed": 0, **kwargs}  # 48: one rollout of 6 slots
    return cls(policy, env, policy_kwargs=policy_kwargs, **settings)


def _labelled(seed: int = 0) -> TeacherLabels:
    return TeacherLabels(SearchVecEnv(WORLD, n_worlds=2, seed=seed), teacher_settings(*TEACHER), seed=0)


@pytest.fixture
def same_minibatches(monkeypatch):
    """sb3-contrib's buffer cut at offset 0 and the whole-slot buffer's slots in order: both form minibatches of the
    same consecutive slots (searchrl/policies/slot_buffer.py), so the updates can be compared."""
    monkeypatch.setattr(np.random, "randint", lambda *args, **kwargs: 0)
    monkeypatch.setattr(np.random, "permutation", lambda n: np.arange(n))


@pytest.mark.usefixtures("same_minibatches")
@pytest.mark.parametrize("base, ours", [(RecurrentPPO, TeacherRecurrentPPO)])
def test_without_weight_or_warmup_the_update_is_sb3s(base, ours):
    """Same seed, same rollouts: after two updates the parameters equal those of SB3's own `train`."""
    reference = _model(base, SearchVecEnv(WORLD, n_worlds=2, seed=0))
    reference.learn(96)
    model = _model(ours, _labelled())
    model.configure_teacher(0.0, "constant", 0, model.get_env())
    model.learn(96)
    assert model.rollouts_trained == 2
    ref, got = reference.policy.state_dict(), model.policy.state_dict()
    for name in ref:
        torch.testing.assert_close(got[name], ref[name], rtol=1e-5, atol=1e-6, msg=name)


def _adam_steps(model) -> int:
    return int(next(iter(model.policy.optimizer.state.values()))["step"])


@pytest.mark.usefixtures("same_minibatches")
@pytest.mark.parametrize("base, ours", [(RecurrentPPO, TeacherRecurrentPPO)])
def test_with_entropy_and_a_kl_stop_the_update_is_still_sb3s(base, ours):
    """Beyond SB3's defaults: with ent_coef > 0 the entropy term is in the loss, and with target_kl the epochs stop
    at the same minibatch as SB3's own `train` (measured: 17 and 12 of 24 minibatch steps), parameters equal."""
    settings = {"batch_size": 16, "n_epochs": 4, "learning_rate": 1e-3, "ent_coef": 0.05, "target_kl": 1e-4}
    reference = _model(base, SearchVecEnv(WORLD, n_worlds=2, seed=0), **settings)
    reference.learn(96)
    model = _model(ours, _labelled(), **settings)
    model.configure_teacher(0.0, "constant", 0, model.get_env())
    model.learn(96)
    steps = _adam_steps(reference)
    assert _adam_steps(model) == steps and 2 < steps < 2 * 4 * 3  # 2 rollouts × 4 epochs × 3 minibatches: stopped
    ref, got = reference.policy.state_dict(), model.policy.state_dict()
    for name in ref:
        torch.testing.assert_close(got[name], ref[name], rtol=1e-5, atol=1e-6, msg=name)


def test_labels_are_the_teachers_actions_on_the_states_acted_in():
    """Acting on the labels replays the teacher itself: the same actions as the teacher driving its own world."""
    env = _labelled()
    env.reset()
    acted = []
    for _ in range(30):  # past an episode end (max_steps 24): teachers restart with their worlds
        action = env._current.copy()
        acted.append(action)
        env.step(action)
    np.testing.assert_array_equal(env.rollout_labels(30), np.stack(acted))
    assert env._acted == []

    world = SearchWorld(WORLD, 2, seed=0)
    maps, vector = world.reset()
    teacher = make_teacher(teacher_settings(*TEACHER), WORLD, 0)
    teacher.reset(world.state, np.ones(2, bool))
    for t in range(30):
        actions = teacher.act(world.state, maps, vector)
        np.testing.assert_array_equal(actions.reshape(-1), acted[t], err_msg=f"step {t}")
        tr = world.step(actions)
        if tr.result.done.any():
            teacher.reset(world.state, tr.result.done)
        maps, vector = tr.maps, tr.vector


def test_labels_cover_every_group_of_a_team_mix():
    mix = TeamMixVecEnv([SearchVecEnv(WORLD, 2, seed=0), SearchVecEnv(replace(WORLD, n_agents=5), 1, seed=1)])
    env = TeacherLabels(mix, teacher_settings(*TEACHER), seed=0)
    env.reset()
    for _ in range(3):
        env.step(env._current)
    labels = env.rollout_labels(3)
    assert labels.shape == (3, 2 * 3 + 5) and labels.min() >= 0 and labels.max() < WORLD.n_actions
    with pytest.raises(RuntimeError, match="fewer than n_steps=3"):
        env.rollout_labels(3)


def _teacher_log_prob(model) -> float:
    """Mean log-probability of the teacher's labels over the last rollout (recomputed with the current weights)."""
    buffer = model.rollout_buffer
    values = []
    with torch.no_grad():
        for data, labels in buffer.get(None):
            _, log_probs, _, mask = model._evaluate(data, labels[None])
            values.append(log_probs[0][mask].mean().item())
    return float(np.mean(values))


def test_the_term_pulls_the_policy_toward_the_teacher():
    """With a large weight, the teacher's actions grow more likely than under plain PPO from the same start."""
    scores = {}
    for weight in (0.0, 5.0):
        model = _model(TeacherRecurrentPPO, _labelled(), learning_rate=3e-3)
        model.n_epochs = 10  # 40 minibatch steps in all; measured: -1.39 with the term, -1.78 without
        model.configure_teacher(weight, "constant", 0, model.get_env())
        model.learn(8 * 6 * 4)
        scores[weight] = _teacher_log_prob(model)
    assert scores[5.0] > scores[0.0] + 0.2, scores


def test_linear_schedule_reaches_zero_and_critic_warmup_leaves_the_policy_alone():
    model = _model(TeacherRecurrentPPO, _labelled())
    model.configure_teacher(2.0, "linear", 2, model.get_env())
    before = {k: v.clone() for k, v in model.policy.state_dict().items()}
    model.learn(96)  # two rollouts: both warm the critic up
    after = model.policy.state_dict()
    moved = {k for k in before if not torch.equal(before[k], after[k])}
    assert moved and all(k.startswith(("value_net", "lstm_critic")) for k in moved), moved
    model._current_progress_remaining = 0.5
    assert model.current_weight() == pytest.approx(1.0)
    model._current_progress_remaining = 0.0
    assert model.current_weight() == 0.0
    with pytest.raises(ValueError, match=r"imitation.rl_schedule=.cosine."):
        model.configure_teacher(1.0, "cosine", 0, None)


def test_training_app_runs_the_term_after_a_clone_and_resumes(tmp_path):
    """Clone, then RL with the term and a warm-up; progress.csv logs the term; a resume keeps the count of
    rollouts trained (no second warm-up); the checkpoint loads as plain RecurrentPPO for evaluation."""
    term = ["imitation.teacher=greedy", "+imitation.teacher_args.horizon=1", "imitation.episodes=1",
            "imitation.epochs=1", "imitation.rl_weight=0.5", "imitation.critic_warmup=2"]  # fmt: skip
    tiny = [o for o in TINY if not o.startswith("total_timesteps=")]
    final = _run(tmp_path, ["+model=b", *tiny, "total_timesteps=1024", *term])
    progress = pd.read_csv(tmp_path / "progress.csv")
    assert progress["time/total_timesteps"].iloc[0] == 0 and progress["val/found_fraction"].notna().iloc[0]  # clone
    assert progress["train/critic_warmup"].notna().sum() == 2
    assert progress["train/imitation_loss"].notna().sum() == 2  # rollouts 3 and 4 of 256 agent-steps
    assert (progress["train/imitation_weight"].dropna() == 0.5).all()
    overrides = [f"resume={tmp_path}", "total_timesteps=1536"]
    train(_compose(overrides), tmp_path / "resumed", overrides)
    resumed = TeacherRecurrentPPO.load(tmp_path / "model.zip")
    assert resumed.rollouts_trained == 6 and resumed.teacher_weight == 0.5
    RecurrentPPO.load(final)  # evaluation reads it with the plain class


class _FixedLabels:
    """A label source that gives the same labels at every update."""

    def __init__(self, labels: np.ndarray) -> None:
        self.labels = labels

    def rollout_labels(self, n_steps: int) -> np.ndarray:
        return self.labels


def test_the_weight_scales_the_terms_gradient_in_the_update():
    """One rollout in one minibatch, one epoch, SGD at rate 1 and no gradient clipping: each update is minus the
    loss's gradient, so the update with weight w less the one with 0 is -w times the gradient of the cross-entropy
    toward the teacher's labels, and a linear schedule halfway through the run weighs it by w/2."""
    model = _model(TeacherRecurrentPPO, _labelled(), n_epochs=1, learning_rate=1.0, max_grad_norm=float("inf"))
    model.train = lambda: None  # collect one rollout without training on it
    model.learn(48)
    del model.train
    labels = _FixedLabels(model.get_env().rollout_labels(8))
    start = {name: value.clone() for name, value in model.policy.state_dict().items()}

    def update(weight: float, schedule: str = "constant", progress: float = 1.0) -> dict[str, torch.Tensor]:
        model.policy.load_state_dict(start)
        model.policy.optimizer = torch.optim.SGD(model.policy.parameters(), lr=1.0)
        model.configure_teacher(weight, schedule, 0, labels)
        model._current_progress_remaining = progress
        set_random_seed(0)  # SB3's global generators: where the rollout buffer splits its sequences
        model.train()
        return {name: value - start[name] for name, value in model.policy.state_dict().items()}

    plain = update(0.0)
    model.policy.load_state_dict(start)
    model.policy.zero_grad(set_to_none=False)
    set_random_seed(0)
    data, batch_labels = next(model.rollout_buffer.get(48))
    _, log_probs, _, mask = model._evaluate(data, batch_labels[None])
    (-log_probs[0][mask].mean()).backward()
    grad = {name: p.grad.clone() for name, p in model.policy.named_parameters()}
    assert max(g.abs().max().item() for g in grad.values()) > 1e-3  # the term has something to move
    for weight, moved in ((0.5, update(0.5)), (2.0, update(2.0)), (0.5, update(1.0, "linear", progress=0.5))):
        for name, g in grad.items():
            torch.testing.assert_close(moved[name] - plain[name], -weight * g, rtol=1e-4, atol=1e-6, msg=name)
