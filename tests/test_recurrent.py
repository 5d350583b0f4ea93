"""The whole-sequence LSTM path (searchrl/policies/recurrent.py) is sb3-contrib's per-step loop in one call per
stretch between episode starts: the same outputs, states and gradients on minibatches whose sequences open episodes
at their heads or inside, and the same PPO update."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch
from sb3_contrib import RecurrentPPO
from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy

from searchrl.envs.vec_env import SearchVecEnv
from searchrl.policies.recurrent import SequenceLstmPolicy, process_sequence
from tests.test_teacher_term import EXTRACTOR, WORLD

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

N_SEQ, LENGTH, WIDTH, HIDDEN = 6, 9, 7, 5


def _batch(starts_at: list[tuple[int, int]], seed: int = 0):
    """features (N_SEQ·LENGTH, WIDTH) requiring grad, states ((1, N_SEQ, HIDDEN) × 2), episode starts with a 1 at
    each (sequence, step) of `starts_at`, and an LSTM."""
    gen = torch.Generator().manual_seed(seed)
    lstm = torch.nn.LSTM(WIDTH, HIDDEN)
    features = torch.randn(N_SEQ * LENGTH, WIDTH, generator=gen, requires_grad=True)
    states = (torch.randn(1, N_SEQ, HIDDEN, generator=gen), torch.randn(1, N_SEQ, HIDDEN, generator=gen))
    starts = torch.zeros(N_SEQ, LENGTH)
    for seq, step in starts_at:
        starts[seq, step] = 1.0
    return features, states, starts.reshape(-1), lstm


def _outputs_and_gradients(fn, features, states, starts, lstm):
    features.grad = None
    lstm.zero_grad()
    out, (h, c) = fn(features, states, starts, lstm)
    (out.square().sum() + h.sum() + 2 * c.sum()).backward()
    return [out, h, c, features.grad, *[p.grad for p in lstm.parameters()]]


@pytest.mark.parametrize("starts_at", [[(0, 0), (3, 0), (5, 0)], [(s, 0) for s in range(N_SEQ)], []])
def test_starts_at_sequence_heads_give_the_loops_outputs_states_and_gradients(starts_at):
    """Starts only at first steps (what the rollout buffer makes): one LSTM call, the loop's arithmetic."""
    batch = _batch(starts_at)
    loop = _outputs_and_gradients(RecurrentActorCriticPolicy._process_sequence, *batch)
    calls = []
    hook = batch[3].register_forward_hook(lambda *_: calls.append(1))
    ours = _outputs_and_gradients(process_sequence, *batch)
    hook.remove()
    assert len(calls) == 1  # one call for the whole minibatch (the loop makes LENGTH when a sequence opens an episode)
    for mine, theirs in zip(ours, loop, strict=True):
        torch.testing.assert_close(mine, theirs, rtol=1e-5, atol=1e-6)
    # A sequence that opens an episode starts from zeros: its outputs do not depend on the stored state
    if starts_at:
        features, (h, c), starts, lstm = batch
        out = process_sequence(features, (h + 1, c - 1), starts, lstm)[0].reshape(N_SEQ, LENGTH, HIDDEN)
        first = starts_at[0][0]
        torch.testing.assert_close(out[first], loop[0].reshape(N_SEQ, LENGTH, HIDDEN)[first])


EVERY_STEP = [(s, t) for s in range(N_SEQ) for t in range(LENGTH)]


@pytest.mark.parametrize(
    "starts_at, n_calls", [([(1, 0), (2, 4)], 2), ([(2, 4), (0, 4), (5, 8), (3, 1)], 4), (EVERY_STEP, LENGTH)]
)
def test_starts_inside_sequences_give_the_loops_arithmetic_one_call_per_stretch(starts_at, n_calls):
    """Starts anywhere (the whole-slot minibatches make them): one LSTM call per stretch between the steps where
    some sequence starts, and the per-step loop's outputs, final states and gradients."""
    batch = _batch(starts_at)
    calls = []
    hook = batch[3].register_forward_hook(lambda *_: calls.append(1))
    ours = _outputs_and_gradients(process_sequence, *batch)
    hook.remove()
    assert len(calls) == n_calls
    loop = _outputs_and_gradients(RecurrentActorCriticPolicy._process_sequence, *batch)
    for mine, theirs in zip(ours, loop, strict=True):
        torch.testing.assert_close(mine, theirs, rtol=1e-5, atol=1e-6)


def test_the_ppo_update_equals_sb3_contribs_on_the_same_rollouts():
    """Same seed, same rollouts, episodes of 20 steps against rollouts of 8 (so minibatch sequences open episodes
    mid-rollout and at a rollout's first step): after six updates the parameters equal sb3-contrib's policy's,
    and the whole-sequence path made fewer LSTM calls."""
    world = replace(WORLD, max_steps=20)
    policy_kwargs = {"features_extractor_kwargs": EXTRACTOR, "net_arch": [], "lstm_hidden_size": 16}
    from searchrl.policies.extractor import SearchCNN

    policy_kwargs["features_extractor_class"] = SearchCNN
    models, calls = [], []
    for policy in ("MultiInputLstmPolicy", SequenceLstmPolicy):
        model = RecurrentPPO(policy, SearchVecEnv(world, n_worlds=2, seed=0), n_steps=8, batch_size=16, n_epochs=2,
                             seed=0, policy_kwargs=policy_kwargs)  # fmt: skip
        count = []
        model.policy.lstm_actor.register_forward_hook(lambda *_, c=count: c.append(1))
        model.learn(8 * 6 * 6)  # 6 slots × 8 steps per rollout, 6 rollouts
        models.append(model)
        calls.append(len(count))
    assert calls[1] < calls[0]
    reference, ours = (m.policy.state_dict() for m in models)
    for name in reference:
        torch.testing.assert_close(ours[name], reference[name], rtol=1e-5, atol=1e-6, msg=name)


def test_a_trained_policy_copies_by_deepcopy_and_by_its_constructor_parameters():
    """After an update SB3 would keep the minibatch's distribution (and its graph) on the policy, which deepcopy
    refuses; sb3-contrib's constructor parameters omit the LSTM's size. Both copies hold the same weights."""
    import copy

    from searchrl.policies.extractor import SearchCNN

    policy_kwargs = {"features_extractor_class": SearchCNN, "features_extractor_kwargs": EXTRACTOR, "net_arch": [],
                     "lstm_hidden_size": 16}  # fmt: skip
    model = RecurrentPPO(SequenceLstmPolicy, SearchVecEnv(WORLD, n_worlds=2, seed=0), n_steps=8, batch_size=16,
                         n_epochs=1, seed=0, policy_kwargs=policy_kwargs)  # fmt: skip
    model.learn(48)
    rebuilt = SequenceLstmPolicy(**model.policy._get_constructor_parameters())
    rebuilt.load_state_dict(model.policy.state_dict())
    for twin in (copy.deepcopy(model.policy), rebuilt):
        for name, value in model.policy.state_dict().items():
            assert torch.equal(twin.state_dict()[name], value), name
