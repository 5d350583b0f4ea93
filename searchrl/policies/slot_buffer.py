"""A recurrent rollout buffer whose minibatches are whole slots' rollouts: no sequence cutting, no padding.

sb3-contrib's `RecurrentDictRolloutBuffer` cuts every slot's rollout at its episode starts and pads the pieces to
one length, minibatch by minibatch, in Python (`create_sequencers`, one `torch.tensor` per field and sequence):
on a GPU that is most of PPO's update (sb3-contrib issue #113, PR #118). CleanRL's `ppo_atari_lstm`, PureJaxRL's
`ppo_rnn` and PufferLib do what this buffer does instead: a minibatch is a set of slots, each with its whole
rollout of `n_steps` steps, started from the LSTM state the slot had at the rollout's first step; an episode start
inside the sequence resets the state there (`searchrl/policies/recurrent.py` runs the LSTM between such steps over
every sequence at once). The arithmetic is the padded buffer's: sb3-contrib's sequences after a start begin from a
reset state too, so where both buffers put the same slots in a minibatch, the losses and gradients are the same
(tests/test_slot_buffer.py).

The rollout is collected in the parent's numpy arrays (n_steps, n_envs, ...) and moved to the policy's device once
per rollout, one transfer per field, slot-major ((n_envs, n_steps, ...)), so a minibatch is one gather on the
device. The teacher term's labels (`set_labels`) ride along: `get` yields (samples, labels (B·n_steps,) int64).
Slots are drawn in a random order each epoch (numpy's global generator, which SB3 seeds); the last minibatch of an
epoch holds the remainder when `batch_size / n_steps` does not divide the slot count.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import torch
from sb3_contrib.common.recurrent.buffers import RecurrentDictRolloutBuffer
from sb3_contrib.common.recurrent.type_aliases import RecurrentDictRolloutBufferSamples, RNNStates


class SlotRolloutBuffer(RecurrentDictRolloutBuffer):
    """RecurrentPPO's rollout buffer with minibatches of whole slots (module docstring); same constructor."""

    def reset(self) -> None:
        super().reset()
        self.labels = np.zeros((self.buffer_size, self.n_envs), np.int64)
        self._slots: dict[str, torch.Tensor] = {}

    def add(self, *args, lstm_states: RNNStates, **kwargs) -> None:
        """SB3's `add`; the LSTM states are kept at the rollout's first step only, all a minibatch starts from (on a
        GPU each kept state is a copy to the host, four a step in sb3-contrib's buffer)."""
        if self.pos == 0:
            super().add(*args, lstm_states=lstm_states, **kwargs)
        else:
            super(RecurrentDictRolloutBuffer, self).add(*args, **kwargs)

    def set_labels(self, labels: np.ndarray) -> None:
        """The teacher's action (n_steps, n_envs) for each step of the rollout just collected."""
        labels = np.asarray(labels, np.int64)
        if labels.shape != (self.buffer_size, self.n_envs):
            raise ValueError(
                f"labels of shape {labels.shape}: expected (n_steps, n_envs) = {(self.buffer_size, self.n_envs)}"
            )
        self.labels = labels
        self._slots.pop("labels", None)

    def _to_slots(self) -> None:
        """Every field on the device, slot-major: (n_envs, n_steps, ...); LSTM states at step 0 only."""

        def slot_major(array: np.ndarray, dtype: torch.dtype = torch.float32) -> torch.Tensor:
            return torch.as_tensor(np.ascontiguousarray(np.swapaxes(array, 0, 1)), dtype=dtype, device=self.device)

        fields = {f"obs/{key}": slot_major(obs) for key, obs in self.observations.items()}
        fields.update(
            {
                name: slot_major(getattr(self, name))
                for name in ("values", "log_probs", "advantages", "returns", "episode_starts")
            }
        )
        fields["actions"] = slot_major(self.actions.reshape(self.buffer_size, self.n_envs, -1))
        for name in ("hidden_states_pi", "cell_states_pi", "hidden_states_vf", "cell_states_vf"):
            # (n_steps, layers, n_envs, hidden) -> each slot's state at its rollout's start: (layers, n_envs, hidden)
            fields[name] = torch.as_tensor(getattr(self, name)[0], device=self.device)
        self._slots = fields

    def get(self, batch_size: int | None = None) -> Iterator[tuple[RecurrentDictRolloutBufferSamples, torch.Tensor]]:
        """(samples, labels) per minibatch of `batch_size // n_steps` whole slots (all slots when None)."""
        assert self.full, "Rollout buffer must be full before sampling from it"
        if not self.generator_ready:
            self._to_slots()
            self.generator_ready = True
        if "labels" not in self._slots:
            self._slots["labels"] = torch.as_tensor(self.labels.T.copy(), device=self.device)
        per_batch = self.n_envs if batch_size is None else max(1, batch_size // self.buffer_size)
        order = np.random.permutation(self.n_envs)  # noqa: NPY002 - the generator SB3's `set_random_seed` seeds
        for start in range(0, self.n_envs, per_batch):
            slots = torch.as_tensor(order[start : start + per_batch], device=self.device)
            yield self._samples(slots), self._slots["labels"][slots].reshape(-1)

    def _samples(self, slots: torch.Tensor) -> RecurrentDictRolloutBufferSamples:
        """Samples of `slots` in sequence-major order: row b·n_steps + t is slot slots[b] at step t."""
        s = self._slots

        def rows(name: str) -> torch.Tensor:
            x = s[name][slots]
            return x.reshape(x.shape[0] * x.shape[1], *x.shape[2:])

        def state(name: str) -> torch.Tensor:
            return s[name][:, slots].contiguous()

        n_rows = len(slots) * self.buffer_size
        return RecurrentDictRolloutBufferSamples(
            observations={key: rows(f"obs/{key}") for key in self.observations},
            actions=rows("actions"),
            old_values=rows("values"),
            old_log_prob=rows("log_probs"),
            advantages=rows("advantages"),
            returns=rows("returns"),
            lstm_states=RNNStates(
                pi=(state("hidden_states_pi"), state("cell_states_pi")),
                vf=(state("hidden_states_vf"), state("cell_states_vf")),
            ),
            episode_starts=rows("episode_starts"),
            mask=torch.ones(n_rows, device=self.device),
        )
