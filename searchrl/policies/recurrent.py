"""sb3-contrib's recurrent policy with its LSTM run over whole sequences during PPO's update.

`RecurrentActorCriticPolicy._process_sequence` (sb3-contrib 2.9) runs the LSTM over a minibatch's padded sequences
in one call only when no step of any sequence starts an episode; otherwise it loops over the time steps in Python,
one LSTM call per step, resetting the state where an episode starts. But the rollout buffer cuts a sequence at every
episode start (`create_sequencers`: a start always opens a new sequence), so a start can only stand at a sequence's
first step, and there resetting the state is the same as starting the sequence from a zero state. This policy does
that: it zeroes the initial state of the sequences that open an episode and runs the LSTM over every sequence at
once, which is the loop's arithmetic in one call (tests/test_recurrent.py: the same outputs and gradients). A start
anywhere else, which no buffer of sb3-contrib 2.9 makes, falls back to the loop.

During a rollout every sequence is one step long, so acting takes the same path.
"""

from __future__ import annotations

import torch
from sb3_contrib.common.recurrent.policies import (
    RecurrentActorCriticPolicy,
    RecurrentMultiInputActorCriticPolicy,
)
from torch import nn

States = tuple[torch.Tensor, torch.Tensor]


def process_sequence(features: torch.Tensor, lstm_states: States, episode_starts: torch.Tensor,
                     lstm: nn.LSTM) -> tuple[torch.Tensor, States]:  # fmt: skip
    """features (n_seq·L, input) in sequence-major order, lstm_states ((layers, n_seq, hidden) × 2), episode_starts
    (n_seq·L,) -> (outputs (n_seq·L, hidden), final states): what sb3-contrib's `_process_sequence` returns."""
    n_seq = lstm_states[0].shape[1]
    starts = episode_starts.reshape(n_seq, -1)
    if bool((starts[:, 1:] != 0).any()):  # a start inside a sequence: the original per-step loop
        return RecurrentActorCriticPolicy._process_sequence(features, lstm_states, episode_starts, lstm)
    keep = (1.0 - starts[:, 0]).view(1, n_seq, 1)  # the loop's reset at the first step, applied to the initial state
    sequences = features.reshape(n_seq, -1, lstm.input_size).swapaxes(0, 1)  # (L, n_seq, input)
    outputs, states = lstm(sequences, (lstm_states[0] * keep, lstm_states[1] * keep))
    return torch.flatten(outputs.transpose(0, 1), start_dim=0, end_dim=1), states


class SequenceLstmPolicy(RecurrentMultiInputActorCriticPolicy):
    """sb3-contrib's `MultiInputLstmPolicy` with `process_sequence` above; the same parameters and saved state."""

    _process_sequence = staticmethod(process_sequence)
