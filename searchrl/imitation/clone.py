"""Warm start by imitation: clone a heuristic teacher (surfing, footprint-greedy, coverage) into the policy before RL.

Not in the paper, which trains from scratch. From scratch, PPO with the paper's rewards plateaus below greedy
local surfing on this grid (docs/results.md); cloning surfing first starts RL from a policy that already climbs
the information, and RL then only has to improve on it. `imitation.teacher=surfing` turns it on;
`imitation.teacher=greedy` clones footprint-greedy, which finds more than surfing on the grid
(`imitation.teacher=greedy_target` its target-greedy settings, any registered heuristic but random), and with
`total_timesteps=0` the run stops after the clone (model.zip is the clone).

Two steps, both before `model.learn`:
1. `collect`: the teacher plays `episodes` episodes in every world of the run's own world groups (same Φ,
   communication and team sizes as the RL rollout). Each slot's episode is one sequence of `max_steps` steps:
   its observations, the teacher's actions, where episodes start (a world that ends early restarts inside the
   sequence) and the discounted return-to-go of the slot's rewards.
2. `clone`: minimise −log π(teacher action | observations so far) over whole sequences, the LSTM starting from
   zeros as at every episode start; then fit the value-only parameters to the returns. The fitted critic means
   PPO's first advantages come from a value that already knows the teacher's returns, so the first updates do not
   undo the clone.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
import torch
from sb3_contrib.common.recurrent.policies import RecurrentActorCriticPolicy
from stable_baselines3.common.policies import ActorCriticPolicy

from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.registry import make_teacher
from searchrl.imitation.teacher_term import value_parameters
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.scenario import PAPER, Scenario


# The registry's controllers but the random walk (nothing to clone); without teacher_args a teacher has the settings
# of controller=<name>.
@dataclass
class Demonstrations:
    """S sequences of T steps, one per slot and teacher episode."""

    maps: np.ndarray  # (S, T, C, fov, fov) float16, C = 5, or 6 with belief_age_channel (observations lie in [0, 1])
    vector: np.ndarray  # (S, T, 3) float32
    actions: np.ndarray  # (S, T) int64, the teacher's
    starts: np.ndarray  # (S, T) float32, 1 where an episode starts inside the sequence (not at t = 0)
    returns: np.ndarray  # (S, T) float32, discounted return-to-go within the episode
    found_fraction: float  # mean found fraction of the teacher's episodes that ended

    def __len__(self) -> int:
        return self.actions.shape[0]


def discounted_returns(rewards: np.ndarray, dones: np.ndarray, gamma: float) -> np.ndarray:
    """(S, T) return-to-go G_t = r_t + γ·G_{t+1}·(1 − done_t); the sequence end is cut without bootstrap."""
    returns = np.zeros_like(rewards)
    running = np.zeros(rewards.shape[0], rewards.dtype)
    for t in range(rewards.shape[1] - 1, -1, -1):  # a loop over time only: slots are vectorised
        running = rewards[:, t] + gamma * running * (1.0 - dones[:, t])
        returns[:, t] = running
    return returns


def collect(
    groups: list[tuple[WorldConfig, int]],
    teacher: ControllerConfig,
    episodes: int,
    gamma: float,
    seed: int,
    scenario: Scenario = PAPER,
) -> Demonstrations:
    """Let `teacher` (a heuristic's settings: `registry.teacher_settings`) play `episodes` rounds in each (world
    config, K) group; round e of group j is seeded (seed, j, e), so the same seed gives the same demonstrations."""
    parts, found = [], []
    for j, (config, n_worlds) in enumerate(groups):
        world = SearchWorld(config, n_worlds, scenario=scenario)
        controller = make_teacher(teacher, config, seed + j)
        steps, slots = config.max_steps, n_worlds * config.n_agents
        for e in range(episodes):
            maps, vector = world.reset(seed=int(np.random.SeedSequence([seed, j, e]).generate_state(1)[0]))
            controller.reset(world.state, np.ones(n_worlds, bool))
            rec = {
                "maps": np.empty((steps, slots, *maps.shape[2:]), np.float16),
                "vector": np.empty((steps, slots, vector.shape[2]), np.float32),
                "actions": np.empty((steps, slots), np.int64),
                "starts": np.zeros((steps, slots), np.float32),
                "rewards": np.empty((steps, slots), np.float32),
                "dones": np.empty((steps, slots), np.float32),
            }
            for t in range(steps):
                actions = controller.act(world.state, maps, vector)
                rec["maps"][t], rec["vector"][t] = maps.reshape(slots, *maps.shape[2:]), vector.reshape(slots, -1)
                rec["actions"][t] = actions.reshape(-1)
                tr = world.step(actions)
                done = tr.result.done
                rec["rewards"][t] = tr.result.reward.reshape(-1)
                rec["dones"][t] = np.repeat(done, config.n_agents)
                if t + 1 < steps:
                    rec["starts"][t + 1] = rec["dones"][t]
                if done.any():
                    controller.reset(world.state, done)
                    found.extend(tr.metrics["found_fraction"][done].tolist())
                maps, vector = tr.maps, tr.vector
            parts.append({key: np.swapaxes(value, 0, 1) for key, value in rec.items()})  # (slots, T, ...)
    cat = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return Demonstrations(
        maps=cat["maps"],
        vector=cat["vector"],
        actions=cat["actions"],
        starts=cat["starts"],
        returns=discounted_returns(cat["rewards"], cat["dones"], gamma),
        found_fraction=float(np.mean(found)) if found else float("nan"),
    )


def _evaluate(policy: ActorCriticPolicy, demos: Demonstrations, idx: np.ndarray) -> tuple[torch.Tensor, ...]:
    """(action distribution, values, teacher actions) of sequences `idx`, flattened sequence-major to B·T rows."""
    device = policy.device
    obs = {
        "map": torch.as_tensor(demos.maps[idx].reshape(-1, *demos.maps.shape[2:]), device=device).float(),
        "vector": torch.as_tensor(demos.vector[idx].reshape(-1, demos.vector.shape[2]), device=device),
    }
    actions = torch.as_tensor(demos.actions[idx].reshape(-1), device=device)
    if isinstance(policy, RecurrentActorCriticPolicy):
        # The batch is read as len(idx) sequences laid end to end, each from zero LSTM states.
        shape = (policy.lstm_actor.num_layers, len(idx), policy.lstm_actor.hidden_size)
        zeros = (torch.zeros(shape, device=device), torch.zeros(shape, device=device))
        starts = torch.as_tensor(demos.starts[idx].reshape(-1), device=device)
        dist, _ = policy.get_distribution(obs, zeros, starts)
        values = policy.predict_values(obs, zeros, starts)
    else:
        dist, values = policy.get_distribution(obs), policy.predict_values(obs)
    return dist, values.flatten(), actions


LR_SCHEDULES = ("constant", "linear")


def lr_factor(schedule: str, step: int, steps: int) -> float:
    """Multiplier of the fit's learning rate at minibatch `step` of `steps` (0-based): 1, or 1 − step/steps."""
    if schedule not in LR_SCHEDULES:
        raise ConfigError(f"imitation.lr_schedule={schedule!r} is not allowed: one of {', '.join(LR_SCHEDULES)}")
    return 1.0 if schedule == "constant" else 1.0 - step / max(steps, 1)  # a phase of 0 epochs has 0 steps


def clone(
    policy: ActorCriticPolicy,
    demos: Demonstrations,
    epochs: int,
    value_epochs: int,
    batch_sequences: int,
    learning_rate: float,
    seed: int,
    on_epoch: Callable[[dict[str, float]], None] | None = None,
    lr_schedule: str = "constant",
) -> list[dict[str, float]]:
    """Fit `policy` in place: `epochs` of cross-entropy on the teacher's actions through the whole network, then
    `value_epochs` of (V − return)² on the value-only parameters. One row of metrics per epoch (phase, imitation
    loss, value loss, accuracy = argmax action is the teacher's, averaged over the epoch's minibatches; learning
    rate of the epoch's last step). `lr_schedule` "linear" takes each phase's rate from `learning_rate` down to 0
    over its minibatches ("constant" keeps it); the shipped C is fitted so, and its small late steps leave fewer
    slips than a constant rate (conf/experiment/clone/c.yaml).

    Why two phases: the returns' squared error is ~20× the imitation loss at the start, and through the shared
    extractor it drowned the imitation gradient (accuracy stayed at the majority action). Why a unit-gain action
    head: SB3 initialises it with gain 0.01 so PPO starts near uniform, which also starves the extractor of
    gradient; the clone's head is re-drawn orthogonally with gain 1 and fitting then starts at once.
    """
    torch.nn.init.orthogonal_(policy.action_net.weight, gain=1.0)
    torch.nn.init.zeros_(policy.action_net.bias)
    rng = np.random.default_rng(seed)
    returns = torch.as_tensor(demos.returns)
    policy.set_training_mode(True)
    history = []
    phases = [("policy", list(policy.parameters()), epochs), ("value", value_parameters(policy), value_epochs)]
    for phase, parameters, n_epochs in phases:
        optimizer = torch.optim.Adam(parameters, lr=learning_rate)  # its own: PPO's Adam starts afresh
        steps = n_epochs * math.ceil(len(demos) / batch_sequences)  # minibatches in the phase
        scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, partial(lr_factor, lr_schedule, steps=steps))
        for _ in range(n_epochs):
            sums = {"imitation_loss": 0.0, "value_loss": 0.0, "accuracy": 0.0}
            order = rng.permutation(len(demos))
            batches = [order[i : i + batch_sequences] for i in range(0, len(order), batch_sequences)]
            for idx in batches:
                dist, values, actions = _evaluate(policy, demos, idx)
                imitation = -dist.log_prob(actions).mean()
                value = torch.nn.functional.mse_loss(values, returns[idx].reshape(-1).to(values.device))
                optimizer.zero_grad()
                (imitation if phase == "policy" else value).backward()
                torch.nn.utils.clip_grad_norm_(parameters, 10.0)  # only against rare spikes
                optimizer.step()
                last_lr = optimizer.param_groups[0]["lr"]
                scheduler.step()
                sums["imitation_loss"] += imitation.item()
                sums["value_loss"] += value.item()
                sums["accuracy"] += (dist.distribution.probs.argmax(dim=1) == actions).float().mean().item()
            row = {"epoch": len(history) + 1, "phase": phase, **{k: v / len(batches) for k, v in sums.items()}}
            row["learning_rate"] = last_lr
            history.append(row)
            if on_epoch:
                on_epoch(row)
    policy.set_training_mode(False)
    return history
