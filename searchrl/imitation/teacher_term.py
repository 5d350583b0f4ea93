"""PPO that keeps what imitation taught: a cross-entropy term toward a teacher's actions inside PPO's own loss.

PPO started from a clone of a heuristic unlearns it (SB3 issue #543; docs/results.md, RL that keeps its teacher): the
first advantages come from a critic that never saw the learner's states, and nothing in PPO's loss holds the policy near
what it was taught. Two remedies, both after PRIMAL (Sartoretti et al. 2019), which never stops imitating, and
kickstarting (Schmitt et al. 2018), which distils toward the teacher with a weight that falls to 0:

- **the teacher term**: every minibatch's loss gains `w · CE(π(·|s), a_teacher(s))` on the states the learner itself
  visited (DAgger's labels, Ross et al. 2011). The teacher reads only the world state, so a VecEnv wrapper labels
  every rollout step online (`searchrl/imitation/teacher_labels.py`). `w` is constant, falls linearly to 0 over the
  run, or (`anneal`) falls linearly to 0 over its first `anneal_steps` agent-steps, whatever the run's budget. It
  is added to the loss rather than taken as a step of its own because Adam is blind to a loss's scale: only in one
  loss does `w` weigh imitation against the PPO terms.
- **critic warm-up**: the first `critic_warmup` rollouts fit only the value-only parameters (value head, critic LSTM)
  on the learner's own returns, and the policy does not move, so the first policy update's advantages come from a
  critic that knows the learner.

With `w = 0` and no warm-up the update is SB3's PPO update exactly (tests/test_teacher_term.py compares parameters).
The labels come from a `LabelSource` and reach the minibatches through the rollout buffer, whose minibatches are
whole slots' rollouts with no padding (`searchrl/policies/slot_buffer.py`); every RecurrentPPO run trains with this
class, the term off (w = 0, no warm-up) where the recipe has none.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
import torch
from sb3_contrib import RecurrentPPO
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.utils import explained_variance

from searchrl.policies.slot_buffer import SlotRolloutBuffer
from searchrl.world.config import ConfigError

SCHEDULES = ("constant", "linear", "anneal")


class LabelSource(Protocol):
    def rollout_labels(self, n_steps: int) -> np.ndarray:
        """(n_steps, n_envs) int64: the teacher's action for the observation each slot acted on, at each step of
        the rollout just collected (the same layout as the rollout buffer's arrays)."""


def check_settings(weight: float, schedule: str, critic_warmup: int) -> None:
    """ValueError naming the `imitation.*` setting that is not allowed (the training app checks them before work)."""
    if not (weight >= 0 and np.isfinite(weight)):
        raise ConfigError(f"imitation.rl_weight={weight!r} is not allowed: a number >= 0 (0: plain PPO)")
    if schedule not in SCHEDULES:
        raise ConfigError(f"imitation.rl_schedule={schedule!r} is not allowed: one of {', '.join(SCHEDULES)}")
    if int(critic_warmup) < 0:
        raise ConfigError(
            f"imitation.critic_warmup={critic_warmup!r} is not allowed: an integer >= 0 (rollouts of "
            "critic-only fitting)"
        )


def value_parameters(policy: ActorCriticPolicy) -> list[torch.nn.Parameter]:
    """The parameters only the value estimate uses: value head, its MLP, (RecurrentPPO) the critic's LSTM and a
    features extractor of the critic's own (searchrl/policies/networks.py)."""
    own = None if policy.share_features_extractor else policy.vf_features_extractor
    modules = [policy.value_net, policy.mlp_extractor.value_net, getattr(policy, "lstm_critic", None), own]
    return [p for m in modules if m is not None for p in m.parameters()]


class TeacherTerm:
    """Mixin for RecurrentPPO (Dict observations): the update above. Set `label_source` before `learn`;
    `teacher_weight`, `teacher_schedule` and `critic_warmup` are saved with the model, `rollouts_trained` too, so
    a resumed run neither warms the critic up again nor restarts the schedule."""

    teacher_weight: float = 0.0
    teacher_schedule: str = "constant"
    teacher_anneal_steps: int = 0
    critic_warmup: int = 0
    rollouts_trained: int = 0
    label_source: LabelSource | None = None

    def configure_teacher(
        self, weight: float, schedule: str, critic_warmup: int, source: LabelSource | None, anneal_steps: int = 0
    ) -> None:
        check_settings(weight, schedule, critic_warmup)
        self.teacher_weight, self.teacher_schedule, self.critic_warmup = float(weight), schedule, int(critic_warmup)
        self.teacher_anneal_steps = int(anneal_steps)
        self.label_source = source

    def _setup_model(self) -> None:
        super()._setup_model()
        old = self.rollout_buffer  # rebuilt as the whole-slot buffer, with the same settings
        self.rollout_buffer = SlotRolloutBuffer(
            old.buffer_size,
            old.observation_space,
            old.action_space,
            hidden_state_shape=old.hidden_state_shape,
            device=old.device,
            gae_lambda=old.gae_lambda,
            gamma=old.gamma,
            n_envs=old.n_envs,
        )

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "label_source"]

    def current_weight(self) -> float:
        """w now: constant, or falling linearly from `teacher_weight` to 0 at the end of the run (`linear`) or at
        agent-step `teacher_anneal_steps` (`anneal`)."""
        if self.teacher_schedule == "linear":
            return self.teacher_weight * max(float(self._current_progress_remaining), 0.0)
        if self.teacher_schedule == "anneal":
            return self.teacher_weight * max(1.0 - self.num_timesteps / max(self.teacher_anneal_steps, 1), 0.0)
        return self.teacher_weight

    def train(self) -> None:
        buffer = self.rollout_buffer
        if self.label_source is not None:
            labels = self.label_source.rollout_labels(buffer.buffer_size)
        elif self.teacher_weight == 0:  # critic warm-up alone: no teacher, the labels are never used
            labels = np.zeros((buffer.buffer_size, buffer.n_envs), np.int64)
        else:
            raise RuntimeError("TeacherTerm.train: teacher_weight > 0 needs a label_source (configure_teacher)")
        buffer.set_labels(labels)
        self.policy.set_training_mode(True)
        self._update_learning_rate(self.policy.optimizer)
        if self.rollouts_trained < self.critic_warmup:
            self._fit_critic()
        else:
            self._ppo_update(self.current_weight())
        self.rollouts_trained += 1

    # --- the two updates ------------------------------------------------------------------------------------
    def _evaluate(self, data: Any, actions: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """(values (B,), log-probabilities (len(actions), B) of each row of `actions` (A, B), entropy (B,), mask
        (B,) bool of real steps). One forward pass: a categorical's log_prob broadcasts over leading dims."""
        values, log_prob, entropy = self.policy.evaluate_actions(
            data.observations, actions, data.lstm_states, data.episode_starts
        )
        return values.flatten(), log_prob, entropy, data.mask > 1e-8

    def _fit_critic(self) -> None:
        """Value loss on the value-only parameters; every other gradient is dropped, so Adam moves nothing else."""
        value_only = {id(p) for p in value_parameters(self.policy)}
        losses = []
        for _ in range(self.n_epochs):
            for data, _labels in self.rollout_buffer.get(self.batch_size):
                actions = data.actions.long().flatten()[None]
                values, _, _, mask = self._evaluate(data, actions)
                loss = ((data.returns - values) ** 2)[mask].mean()
                self.policy.optimizer.zero_grad(set_to_none=True)
                loss.backward()
                for p in self.policy.parameters():
                    if id(p) not in value_only:
                        p.grad = None
                torch.nn.utils.clip_grad_norm_(self.policy.parameters(), self.max_grad_norm)
                self.policy.optimizer.step()
                losses.append(loss.item())
        self.logger.record("train/value_loss", float(np.mean(losses)))
        self.logger.record("train/critic_warmup", 1)

    def _ppo_update(self, weight: float) -> None:
        """SB3's clipped PPO update (clipped ratio, value and entropy terms, advantage normalisation, KL stop),
        plus `weight` × the cross-entropy toward the teacher's labels."""
        clip_range = self.clip_range(self._current_progress_remaining)
        clip_vf = None if self.clip_range_vf is None else self.clip_range_vf(self._current_progress_remaining)
        logs: dict[str, list[float]] = {k: [] for k in ("pg", "value", "entropy", "imitation", "clip", "kl")}
        continue_training = True
        for _ in range(self.n_epochs):
            approx_kls = []
            for data, labels in self.rollout_buffer.get(self.batch_size):
                actions = data.actions.long().flatten()  # Discrete actions (every searchrl action set)
                values, log_probs, entropy, mask = self._evaluate(data, torch.stack([actions, labels]))
                log_prob, teacher_log_prob = log_probs[0], log_probs[1]
                advantages = data.advantages
                if self.normalize_advantage:
                    advantages = (advantages - advantages[mask].mean()) / (advantages[mask].std() + 1e-8)
                ratio = torch.exp(log_prob - data.old_log_prob)
                clipped = torch.clamp(ratio, 1 - clip_range, 1 + clip_range)
                surrogate = torch.min(advantages * ratio, advantages * clipped)
                policy_loss = -surrogate[mask].mean()
                if clip_vf is not None:
                    values = data.old_values + torch.clamp(values - data.old_values, -clip_vf, clip_vf)
                value_loss = ((data.returns - values) ** 2)[mask].mean()
                entropy_loss = -entropy[mask].mean()
                imitation_loss = -teacher_log_prob[mask].mean()
                loss = policy_loss + self.ent_coef * entropy_loss + self.vf_coef * value_loss
                if weight > 0:
                    loss = loss + weight * imitation_loss
                with torch.no_grad():
                    log_ratio = log_prob - data.old_log_prob
                    approx_kls.append(((torch.exp(log_ratio) - 1) - log_ratio)[mask].mean().item())
                for key, value in (
                    ("pg", policy_loss),
                    ("value", value_loss),
                    ("entropy", entropy_loss),
                    ("imitation", imitation_loss),
                ):
                    logs[key].append(value.item())
                logs["clip"].append(((ratio - 1).abs() > clip_range).float()[mask].mean().item())
                if self.target_kl is not None and approx_kls[-1] > 1.5 * self.target_kl:
                    continue_training = False
                    break
                self.policy.optimizer.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(self.policy.parameters(), self.max_grad_norm)
                self.policy.optimizer.step()
            logs["kl"] = approx_kls
            self._n_updates += 1
            if not continue_training:
                break
        buffer = self.rollout_buffer
        logged = [
            ("policy_gradient_loss", "pg"),
            ("value_loss", "value"),
            ("entropy_loss", "entropy"),
            ("clip_fraction", "clip"),
            ("approx_kl", "kl"),
        ]
        if self.label_source is not None:  # without a teacher the labels are placeholders: nothing to log
            logged.append(("imitation_loss", "imitation"))
            self.logger.record("train/imitation_weight", weight)
        for name, key in logged:
            self.logger.record(f"train/{name}", float(np.mean(logs[key])) if logs[key] else float("nan"))
        self.logger.record("train/loss", loss.item())
        self.logger.record(
            "train/explained_variance", explained_variance(buffer.values.flatten(), buffer.returns.flatten())
        )
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/clip_range", clip_range)


class TeacherRecurrentPPO(TeacherTerm, RecurrentPPO):
    """RecurrentPPO with the teacher term and critic warm-up."""


TEACHER_ALGORITHMS: dict[str, type] = {"recurrent_ppo": TeacherRecurrentPPO}
