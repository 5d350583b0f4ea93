"""The actor half of a trained SB3 policy, for fast batched inference.

SB3's `predict` runs the whole policy through its generic path and samples with torch's global generator. For
evaluation we need only the actor, on large batches, with reproducible sampling, so `Actor`
- traces and freezes the features extractor (TorchScript with the conv layers fused for inference; once about 3x
  faster than eager on the CPU, now as fast as eager's channels-last convolutions: `python -m searchrl.bench
  policy`), or runs it with ONNX Runtime (`inference="onnx"`, searchrl/policies/onnx_extractor.py),
- calls the actor LSTM (RecurrentPPO) and the action head directly, on any subset of rows, and
- leaves sampling to the caller (`sample_actions`, from uniforms the caller draws).
Its logits equal the policy's own distribution logits to float32 rounding (tested).

The network runs on the actor's device; the world, the LSTM state the caller holds and the sampling stay on the CPU
in numpy (observations go to the device, logits and states come back). On the CPU every step is bit for bit what
it was before devices existed (tests/test_golden.py). CUDA rounds otherwise: cuDNN convolutions run in TF32 by
torch's default, and the shipped policies' logits differ from the CPU's by up to about 5e-2 (an H200), which flips
one or two sampled or argmax actions in a thousand. `policy_copy` makes the copy an actor acts with when the policy
it copies must stay as it is (validation).
"""

from __future__ import annotations

import warnings

import numpy as np
import torch
from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.policies import ActorCriticPolicy
from torch import nn

from searchrl.envs.parts import make_parts
from searchrl.world.config import ConfigError

# The inference paths of a CPU actor: "torch", the traced and frozen TorchScript extractor every golden episode was
# recorded with; "onnx", the extractor run by ONNX Runtime, faster and not bit for bit (searchrl/policies/
# onnx_extractor.py). An evaluation records its path.
INFERENCE = ("torch", "onnx")


def check_inference(inference: str, device: str | torch.device = "cpu") -> None:
    """ValueError in one line for an unknown path, or the onnx path on a device that is not the CPU."""
    if inference not in INFERENCE:
        raise ConfigError(f"inference={inference!r} is not allowed: one of {', '.join(INFERENCE)}")
    if inference == "onnx" and torch.device(device).type != "cpu":
        raise ConfigError(f"inference=onnx runs on the CPU, not device={str(device)!r}: use inference=torch there")


def _optimized(extractor: nn.Module, example: dict[str, torch.Tensor]) -> nn.Module:
    """The extractor traced, frozen and optimised for inference; the eager module where tracing fails or the result
    strays from eager's. The check runs on the example's device: `optimize_for_inference` chooses its passes by
    device (MKL-DNN layouts on the CPU only), so a pass that changes the arithmetic is caught on each."""
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


def policy_copy(model: OnPolicyAlgorithm) -> ActorCriticPolicy:
    """A new policy holding `model`'s policy's weights, on the model's device, built as the model built its own
    (`_setup_model`: its policy class, spaces, schedule and policy_kwargs) and loaded with `load_state_dict`.

    Not `copy.deepcopy`: SB3's ActorCriticPolicy keeps its last action distribution, with that minibatch's autograd
    graph, which deepcopy refuses after an update. Not the policy's `_get_constructor_parameters` alone: SB3 2.9
    leaves out share_features_extractor there and sb3-contrib 2.9 every LSTM setting. Building draws initial weights
    from torch's global CPU generator, which training samples its actions from: it is restored afterwards, so a copy
    does not shift a run's sampling."""
    # ortho_init off: the weights are overwritten below, and orthogonal init (a QR per layer) takes 0.8 s of the
    # paper network's 0.9 s build; it changes no layer. Built on the CPU: only the CPU generator is drawn from.
    kwargs = {**model.policy_kwargs, "ortho_init": False}
    with torch.random.fork_rng(devices=[]):
        twin = model.policy_class(
            model.observation_space, model.action_space, model.lr_schedule, use_sde=model.use_sde, **kwargs
        )
    twin.to(model.device)
    twin.load_state_dict(model.policy.state_dict())  # strict: a setting the build missed fails here, by name
    return twin


class Actor:
    """Logits of a trained ActorCriticPolicy (PPO, A2C) or RecurrentActorCriticPolicy (RecurrentPPO).

    Stateless: the caller keeps each slot's LSTM state (`initial_state`) and passes the rows it acts for.
    """

    def __init__(
        self,
        policy: ActorCriticPolicy,
        optimize: bool = True,
        device: str | torch.device = "cpu",
        inference: str = "torch",
    ) -> None:
        """Act with `policy`, moved to `device` and put in evaluation mode: the actor owns it from now on (pass
        `policy_copy(model)` to keep a policy that trains on as it is). `inference` is the extractor's path
        (INFERENCE); `optimize=False` keeps torch's eager extractor (the reference the others are checked against)."""
        check_inference(inference, device)
        if not isinstance(policy, ActorCriticPolicy):
            raise TypeError(f"policy of type {type(policy).__name__} is not an SB3 ActorCriticPolicy")
        self.device = torch.device(device)
        policy.to(self.device)  # in place: a no-op for a policy already there
        policy.set_training_mode(False)
        self.recurrent = isinstance(policy, RecurrentActorCriticPolicy)
        self.n_actions = int(policy.action_space.n)
        self._mlp = policy.mlp_extractor
        self._head = policy.action_net
        self._lstm: nn.LSTM | None = policy.lstm_actor if self.recurrent else None
        space = policy.observation_space
        extractor = policy.pi_features_extractor
        # The keys the actor's extractor reads: "map", "vector" and its observation parts, never a critic's own
        # input (searchrl/policies/networks.py), so an actor runs where no true state exists.
        self.keys = tuple(getattr(extractor, "keys", space.spaces))
        # The parts to observe for it, each on the grid its space says (a part's one setting).
        self.parts = make_parts((name, {"grid": space[name].shape[-1]}) for name in getattr(extractor, "parts", ()))
        example = {
            k: torch.as_tensor(np.stack([space[k].sample() for _ in range(4)]), device=self.device) for k in self.keys
        }
        self.inference = inference
        if inference == "onnx":
            from searchrl.policies.onnx_extractor import OnnxExtractor  # onnxruntime loads only for this path

            self._extract = OnnxExtractor(extractor, self.keys, example)
        else:
            self._extract = _optimized(extractor, example) if optimize else extractor

    def initial_state(self, batch: int) -> torch.Tensor | None:
        """Zero LSTM state (2, layers, batch, hidden) float32 — hidden and cell — on the actor's device (it stays
        there between steps: only observations go to the device and logits come back), or None without an LSTM."""
        if self._lstm is None:
            return None
        return torch.zeros((2, self._lstm.num_layers, batch, self._lstm.hidden_size), device=self.device)

    @torch.inference_mode()
    def logits(
        self,
        maps: np.ndarray,
        vector: np.ndarray,
        state: torch.Tensor | None = None,
        parts: dict[str, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, torch.Tensor | None]:
        """maps (B, C, F, F), vector (B, V), state (2, layers, B, hidden) on the actor's device or None, and the
        actor's observation parts {key: (B, ...)} (`self.parts`) -> (logits (B, n_actions) float32, next state on
        the device). A slot whose episode starts now gets a zero state (`initial_state`)."""
        parts = {"map": maps, "vector": vector, **(parts or {})}
        # `.to` and `.cpu` return the very tensor on the CPU: no copy, the same arithmetic as before devices
        obs = {k: torch.from_numpy(np.ascontiguousarray(parts[k], np.float32)).to(self.device) for k in self.keys}
        features = self._extract(obs)
        if self._lstm is not None:
            if state is None:
                raise ValueError("a recurrent policy needs its LSTM state: start from initial_state(batch)")
            h, c = state
            out, (h, c) = self._lstm(features.unsqueeze(0), (h.contiguous(), c.contiguous()))
            features, state = out.squeeze(0), torch.stack([h, c])
        return self._head(self._mlp.forward_actor(features)).cpu().numpy(), state


def sample_actions(logits: np.ndarray, uniforms: np.ndarray | None) -> np.ndarray:
    """(B, A) logits -> (B,) int64 actions: drawn from softmax(logits) by inverting its CDF at `uniforms` (B,) in
    [0, 1), or argmax when uniforms is None."""
    if uniforms is None:
        return logits.argmax(axis=1).astype(np.int64)
    z = logits.astype(np.float64) - logits.max(axis=1, keepdims=True)
    cdf = np.cumsum(np.exp(z), axis=1)
    u = np.asarray(uniforms) * cdf[:, -1]
    return np.minimum((cdf < u[:, None]).sum(axis=1), logits.shape[1] - 1).astype(np.int64)
