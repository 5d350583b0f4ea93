"""sb3-contrib's recurrent policy with its LSTM run over whole sequences during PPO's update.

`RecurrentActorCriticPolicy._process_sequence` (sb3-contrib 2.9) runs the LSTM over a minibatch's sequences in one
call only when no step of any sequence starts an episode; otherwise it loops over the time steps in Python, one LSTM
call per step, resetting the state of the sequences whose episode starts at that step. The loop's arithmetic needs
a reset only at the steps where some sequence starts: between two such steps the LSTM can run over every sequence
at once. `process_sequence` does that: one LSTM call per stretch between starting steps (one call when starts stand
only at the sequences' heads, as sb3-contrib's buffer cuts them; a few in the whole-slot minibatches of
searchrl/policies/slot_buffer.py, where a slot's episode may start anywhere in its rollout), with the state of the
starting sequences zeroed at the stretch's first step (tests/test_recurrent.py: the loop's outputs and gradients).

During a rollout every sequence is one step long, so acting takes the same path.
"""

from __future__ import annotations

import copy
from typing import Any

import torch
from gymnasium import spaces
from sb3_contrib.common.recurrent.policies import RecurrentMultiInputActorCriticPolicy
from stable_baselines3.common.distributions import Distribution
from torch import nn

States = tuple[torch.Tensor, torch.Tensor]


def process_sequence(
    features: torch.Tensor, lstm_states: States, episode_starts: torch.Tensor, lstm: nn.LSTM
) -> tuple[torch.Tensor, States]:
    """features (n_seq·L, input) in sequence-major order, lstm_states ((layers, n_seq, hidden) × 2), episode_starts
    (n_seq·L,) -> (outputs (n_seq·L, hidden), final states): what sb3-contrib's `_process_sequence` returns."""
    n_seq = lstm_states[0].shape[1]
    starts = episode_starts.reshape(n_seq, -1)
    sequences = features.reshape(n_seq, -1, lstm.input_size).swapaxes(0, 1)  # (L, n_seq, input)
    length = sequences.shape[0]
    # The steps after the first where some sequence starts an episode (one small host read of a (L,) mask; none
    # when acting, one step at a time, so a rollout on a GPU does not wait for it).
    cuts = (torch.nonzero(starts[:, 1:].any(dim=0)).flatten() + 1).tolist() if length > 1 else []
    h, c = lstm_states
    outputs = []
    for first, end in zip([0, *cuts], [*cuts, length], strict=True):
        keep = (1.0 - starts[:, first]).view(1, n_seq, 1)  # the loop's reset of the sequences starting here
        out, (h, c) = lstm(sequences[first:end], (h * keep, c * keep))
        outputs.append(out)
    out = outputs[0] if len(outputs) == 1 else torch.cat(outputs)
    return torch.flatten(out.transpose(0, 1), start_dim=0, end_dim=1), (h, c)


class SequenceLstmPolicy(RecurrentMultiInputActorCriticPolicy):
    """sb3-contrib's `MultiInputLstmPolicy` with `process_sequence` above; the same parameters and saved state."""

    _process_sequence = staticmethod(process_sequence)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        # sb3-contrib's omits the LSTM's settings, so a policy built from it (SB3's way to copy or load a policy
        # alone) would get the default 256-wide LSTM and refuse the weights.
        data = super()._get_constructor_parameters()
        data.update(
            lstm_hidden_size=self.lstm_actor.hidden_size,
            n_lstm_layers=self.lstm_actor.num_layers,
            shared_lstm=self.shared_lstm,
            enable_critic_lstm=self.enable_critic_lstm,
            lstm_kwargs=self.lstm_kwargs,
        )
        return data

    def _get_action_dist_from_latent(self, latent_pi: torch.Tensor) -> Distribution:
        # SB3 fills the policy's one `action_dist` in place, so after an update the policy holds that minibatch's
        # logits and their graph, and `copy.deepcopy(policy)` fails ("Only Tensors created explicitly by the user
        # support the deepcopy protocol"). Each call fills a shallow copy instead: the policy keeps no graph.
        shared = self.action_dist
        self.action_dist = copy.copy(shared)
        try:
            return super()._get_action_dist_from_latent(latent_pi)
        finally:
            self.action_dist = shared


class OwnCriticLstmPolicy(SequenceLstmPolicy):
    """`SequenceLstmPolicy` whose critic has a features extractor of its own class, `critic_extractor_class`
    (searchrl/policies/networks.py), built with the actor's widths (`features_extractor_kwargs` less the actor's
    own settings) and its own settings (`critic_extractor_kwargs`), feeding the critic's LSTM; the actor's
    extractor, LSTM and head are the ones a shared policy has, under the same names. `critic_keys` ({part name:
    observation key}, searchrl/policies/networks.py `critic_keys`) are the parts the critic reads from its own copy:
    its extractor sees each copy under the part's name."""

    WIDTHS = ("conv_channels", "vector_size", "fc_sizes")

    def __init__(
        self,
        *args: Any,
        critic_extractor_class: type[nn.Module],
        critic_extractor_kwargs: dict[str, Any] | None = None,
        critic_keys: dict[str, str] | None = None,
        **kwargs: Any,
    ) -> None:
        self.critic_extractor_class = critic_extractor_class
        self.critic_extractor_kwargs = dict(critic_extractor_kwargs or {})
        self.critic_keys = dict(critic_keys or {})
        super().__init__(*args, **{**kwargs, "share_features_extractor": False})

    def make_features_extractor(self) -> nn.Module:
        # SB3's ActorCriticPolicy.__init__ calls this for the actor's extractor, then (not shared) for the critic's.
        if not isinstance(getattr(self, "features_extractor", None), nn.Module):
            return super().make_features_extractor()
        widths = {k: v for k, v in self.features_extractor_kwargs.items() if k in self.WIDTHS}
        space = self.observation_space
        if self.critic_keys:  # the critic's copies, each seen under its part's name
            space = spaces.Dict({**space.spaces, **{name: space[key] for name, key in self.critic_keys.items()}})
        critic = self.critic_extractor_class(space, **widths, **self.critic_extractor_kwargs)
        if critic.features_dim != self.features_extractor.features_dim:  # the critic's LSTM takes the actor's width
            raise ValueError(
                f"the critic's features ({critic.features_dim}) must be as wide as the actor's "
                f"({self.features_extractor.features_dim})"
            )
        return ReadsCopies(critic, self.critic_keys) if self.critic_keys else critic

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return {
            **super()._get_constructor_parameters(),
            "critic_extractor_class": self.critic_extractor_class,
            "critic_extractor_kwargs": self.critic_extractor_kwargs,
            **({"critic_keys": self.critic_keys} if self.critic_keys else {}),
        }


class ReadsCopies(nn.Module):
    """An extractor that reads, under a part's name, the observation held under another key ({name: key})."""

    def __init__(self, extractor: nn.Module, keys: dict[str, str]) -> None:
        super().__init__()
        self.extractor, self.keys = extractor, keys
        self.features_dim = extractor.features_dim

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        return self.extractor({**observations, **{name: observations[key] for name, key in self.keys.items()}})
