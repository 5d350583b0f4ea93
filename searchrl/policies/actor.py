"""The actor half of a trained SB3 policy, for fast batched inference.

SB3's `predict` runs the whole policy through its generic path and samples with torch's global generator. For
evaluation we need only the actor, on large batches, with reproducible sampling, so `Actor`
- traces and freezes the features extractor (TorchScript with the conv layers fused for inference: about 3x
  faster than eager on CPU for the paper network),
- calls the actor LSTM (RecurrentPPO) and the action head directly, on any subset of rows, and
- leaves sampling to the caller (`sample_actions`, from uniforms the caller draws).
Its logits equal the policy's own distribution logits to float32 rounding (tested).
"""

from __future__ import annotations

import warnings

import numpy as np
import torch
from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy
from stable_baselines3.common.policies import ActorCriticPolicy
from torch import nn


def _optimized(extractor: nn.Module, example: dict[str, torch.Tensor]) -> nn.Module:
    """The extractor traced, frozen and optimised for inference; the eager module where tracing fails."""
    try:
        with torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore")  # tracer warnings about Python values; the check below decides
            traced = torch.jit.trace(extractor, (example,), strict=False)
            frozen = torch.jit.optimize_for_inference(torch.jit.freeze(traced.eval()))
            if torch.allclose(frozen(example), extractor(example), rtol=1e-4, atol=1e-5):
                return frozen
    except (RuntimeError, TypeError, ValueError):
        pass
    return extractor


class Actor:
    """Logits of a trained ActorCriticPolicy (PPO, A2C) or RecurrentActorCriticPolicy (RecurrentPPO).

    Stateless: the caller keeps each slot's LSTM state (`initial_state`) and passes the rows it acts for.
    """

    def __init__(self, policy: ActorCriticPolicy, optimize: bool = True) -> None:
        if not isinstance(policy, ActorCriticPolicy):
            raise TypeError(f"policy of type {type(policy).__name__} is not an SB3 ActorCriticPolicy")
        policy.set_training_mode(False)
        self.recurrent = isinstance(policy, RecurrentActorCriticPolicy)
        self.n_actions = int(policy.action_space.n)
        self._mlp = policy.mlp_extractor
        self._head = policy.action_net
        self._lstm: nn.LSTM | None = policy.lstm_actor if self.recurrent else None
        space = policy.observation_space
        self.keys = tuple(space.spaces)  # "map", "vector"
        example = {k: torch.as_tensor(np.stack([space[k].sample() for _ in range(4)])) for k in self.keys}
        extractor = policy.pi_features_extractor
        self._extract = _optimized(extractor, example) if optimize else extractor

    def initial_state(self, batch: int) -> np.ndarray | None:
        """Zero LSTM state (2, layers, batch, hidden) float32 — hidden and cell — or None without an LSTM."""
        if self._lstm is None:
            return None
        return np.zeros((2, self._lstm.num_layers, batch, self._lstm.hidden_size), np.float32)

    @torch.inference_mode()
    def logits(
        self, maps: np.ndarray, vector: np.ndarray, state: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """maps (B, C, F, F), vector (B, V), state (2, layers, B, hidden) or None -> (logits (B, n_actions) float32,
        next state). A slot whose episode starts now gets a zero state (`initial_state`)."""
        parts = {"map": maps, "vector": vector}
        obs = {k: torch.from_numpy(np.ascontiguousarray(parts[k], np.float32)) for k in self.keys}
        features = self._extract(obs)
        if self._lstm is not None:
            if state is None:
                raise ValueError("a recurrent policy needs its LSTM state: start from initial_state(batch)")
            h, c = torch.from_numpy(np.ascontiguousarray(state, np.float32))
            out, (h, c) = self._lstm(features.unsqueeze(0), (h.contiguous(), c.contiguous()))
            features, state = out.squeeze(0), torch.stack([h, c]).numpy()
        return self._head(self._mlp.forward_actor(features)).numpy(), state


def sample_actions(logits: np.ndarray, uniforms: np.ndarray | None) -> np.ndarray:
    """(B, A) logits -> (B,) int64 actions: drawn from softmax(logits) by inverting its CDF at `uniforms` (B,) in
    [0, 1), or argmax when uniforms is None."""
    if uniforms is None:
        return logits.argmax(axis=1).astype(np.int64)
    z = logits.astype(np.float64) - logits.max(axis=1, keepdims=True)
    cdf = np.cumsum(np.exp(z), axis=1)
    u = np.asarray(uniforms) * cdf[:, -1]
    return np.minimum((cdf < u[:, None]).sum(axis=1), logits.shape[1] - 1).astype(np.int64)
