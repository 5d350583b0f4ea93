"""The whole-slot recurrent buffer (searchrl/policies/slot_buffer.py): minibatches that are whole slots' rollouts in
sequence-major order, each slot once per epoch, labels on their rows, the LSTM state each slot entered its rollout
with; and PPO's update equal to sb3-contrib's padded buffer where both form the same minibatches, with episode
starts inside the rollouts."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from sb3_contrib import RecurrentPPO

from searchrl.envs.vec_env import SearchVecEnv
from searchrl.imitation.teacher_term import TeacherRecurrentPPO
from searchrl.policies.slot_buffer import SlotRolloutBuffer
from tests.test_teacher_term import WORLD, _model

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

SHORT = replace(WORLD, max_steps=20)  # episodes of 20 steps, rollouts of 8: starts at rollout heads and inside


def _collected(n_worlds: int = 2) -> TeacherRecurrentPPO:
    """A model whose buffer holds one rollout (8 steps × 3·n_worlds slots), not trained on."""
    model = _model(TeacherRecurrentPPO, SearchVecEnv(SHORT, n_worlds=n_worlds, seed=0))
    model.train = lambda: None
    model.learn(8 * 3 * n_worlds * 3)  # three rollouts: the third holds an episode start at its step 4
    return model


def test_minibatches_are_whole_slots_in_sequence_major_order():
    model = _collected()
    buffer = model.rollout_buffer
    assert isinstance(buffer, SlotRolloutBuffer)
    assert buffer.episode_starts[1:].any()  # a start inside a slot's rollout
    labels = np.arange(buffer.buffer_size * buffer.n_envs).reshape(buffer.buffer_size, buffer.n_envs) % 5
    buffer.set_labels(labels)
    seen = []
    for data, batch_labels in buffer.get(16):  # 16 agent-steps: two slots of 8 steps
        n_slots = len(data.old_values) // buffer.buffer_size
        assert n_slots == 2 and data.lstm_states.pi[0].shape[1] == 2 and bool(data.mask.all())
        values = data.old_values.reshape(n_slots, buffer.buffer_size).numpy()
        for b in range(n_slots):
            slot = int(np.flatnonzero((buffer.values.T == values[b]).all(axis=1))[0])
            seen.append(slot)
            np.testing.assert_array_equal(batch_labels.reshape(n_slots, -1)[b].numpy(), labels[:, slot])
            np.testing.assert_array_equal(data.episode_starts.reshape(n_slots, -1)[b].numpy(),
                                          buffer.episode_starts[:, slot])  # fmt: skip
            np.testing.assert_array_equal(data.actions.reshape(n_slots, -1)[b].numpy(), buffer.actions[:, slot, 0])
            for key, obs in data.observations.items():
                np.testing.assert_array_equal(obs.reshape(n_slots, buffer.buffer_size, *obs.shape[1:])[b].numpy(),
                                              buffer.observations[key][:, slot])  # fmt: skip
            np.testing.assert_array_equal(data.lstm_states.vf[1][:, b].numpy(), buffer.cell_states_vf[0][:, slot])
    assert sorted(seen) == list(range(buffer.n_envs))  # each slot once per epoch


def test_a_remainder_minibatch_and_refused_labels():
    model = _collected()
    sizes = [len(data.old_values) for data, _ in model.rollout_buffer.get(32)]  # 4 slots, then the 2 left
    assert sizes == [32, 16]
    with pytest.raises(ValueError, match=r"expected \(n_steps, n_envs\) = \(8, 6\)"):
        model.rollout_buffer.set_labels(np.zeros((6, 8), np.int64))


@pytest.mark.parametrize("batch_size", [16, 48])
def test_the_update_equals_sb3_contribs_padded_buffer_on_the_same_minibatches(monkeypatch, batch_size):
    """Six rollouts whose slots open episodes mid-rollout: when sb3-contrib cuts its buffer at offset 0 and the
    slots come in order, both buffers' minibatches hold the same steps, and after six updates the parameters are
    equal (the padded sequences after a start begin from a reset state, as the whole slot does there)."""
    monkeypatch.setattr(np.random, "randint", lambda *args, **kwargs: 0)
    monkeypatch.setattr(np.random, "permutation", lambda n: np.arange(n))
    inside = []  # per rollout of the whole-slot run: does a slot open an episode after its first step?
    to_slots = SlotRolloutBuffer._to_slots
    monkeypatch.setattr(
        SlotRolloutBuffer,
        "_to_slots",
        lambda self: inside.append(bool(self.episode_starts[1:].any())) or to_slots(self),
    )
    models = []
    for cls in (RecurrentPPO, TeacherRecurrentPPO):
        model = _model(cls, SearchVecEnv(SHORT, n_worlds=2, seed=0), batch_size=batch_size)
        model.learn(8 * 6 * 6)
        models.append(model)
    assert inside == [False, False, True, False, False, False]  # episodes start at steps 20 (inside) and 40
    reference, ours = (m.policy.state_dict() for m in models)
    for name in reference:
        torch.testing.assert_close(ours[name], reference[name], rtol=1e-5, atol=1e-6, msg=name)
