"""SB3 training throughput: RecurrentPPO on the VecEnv for a fixed number of updates, with the paper network on
model B's training scenarios, or a recipe (`--experiment`, e.g. one with the teacher term). Reports agent-steps/s
and where the wall time goes: the environment's steps, the teacher's labels (runs with the teacher term), the
updates (`train`); the rest is the policy acting during the rollout and SB3's bookkeeping.

In the same run, the raw bound: the recipe's network alone on the last rollout's own minibatches (taken from the
rollout buffer before the clock starts), forward + backward + Adam step, the recipe's epochs, in plain torch with
no SB3 code in the timed loop. The recipe cannot train faster than that; the ratio says how close it comes."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TextIO

import torch
from hydra import compose, initialize_config_dir

from searchrl.policies.recurrent import process_sequence
from searchrl.train.__main__ import CONF_DIR
from searchrl.train.build import make_algorithm, make_vec_env
from searchrl.train.plan import make_plan
from searchrl.train.teacher_labels import TeacherLabels


def _timed(fn: Callable, total: list[float]) -> Callable:
    def timed(*args, **kwargs):
        start = time.perf_counter()
        out = fn(*args, **kwargs)
        total[0] += time.perf_counter() - start
        return out

    return timed


def run(updates: int = 4, threads: int = 2, network: str = "paper", experiment: str | None = None,
        log: TextIO | None = None) -> list[dict]:  # fmt: skip
    """One run of `updates` rollouts (plus one warm-up rollout, not timed); `experiment` composes
    `+experiment=<name>` (its own model and network) instead of model B on the paper's recipe with `network`."""
    overrides = [f"+experiment={experiment}"] if experiment else ["+model=b", f"network={network}"]
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="train", overrides=[*overrides, f"threads={threads}"])
    # The few timed rollouts would all fall in a recipe's critic warm-up (its first rollouts, value-only updates):
    # time the updates the rest of the run makes.
    cfg.imitation.critic_warmup = 0
    torch.set_num_threads(threads)
    plan = make_plan(cfg)
    env = make_vec_env(plan, seed=0)
    base = env.venv if isinstance(env, TeacherLabels) else env
    spent = {"env": [0.0], "labels": [0.0], "update": [0.0]}
    base.step_wait = _timed(base.step_wait, spent["env"])
    if isinstance(env, TeacherLabels):
        env._label = _timed(env._label, spent["labels"])
    model = make_algorithm(plan, env)
    model.train = _timed(model.train, spent["update"])
    rollout = plan.rollout
    model.learn(rollout)  # warm-up: numba cache, torch kernels
    for total in spent.values():
        total[0] = 0.0
    start = time.perf_counter()
    model.learn(rollout * updates, reset_num_timesteps=False)
    wall = time.perf_counter() - start
    fps = rollout * updates / wall
    raw = raw_bound(model, updates)
    name = experiment or f"recurrent_ppo_{network}_model_b_K{cfg.env.n_worlds}_N{cfg.env.world.n_agents}"
    row = {"case": f"{name}_threads{threads}", "engine": "sb3", "agent_steps_per_s": round(fps, 1),
           "raw_bound_agent_steps_per_s": round(raw, 1), "ratio_to_raw_bound": round(fps / raw, 3)}  # fmt: skip
    row.update({f"{part}_share": round(total[0] / wall, 4) for part, total in spent.items()})
    if log:
        shares = ", ".join(f"{part} {100 * row[f'{part}_share']:.1f}%" for part in spent)
        print(f"{row['case']}: {fps:,.0f} agent-steps/s over {updates} updates of {rollout} agent-steps; "
              f"wall time: {shares}, the rest acting and bookkeeping", file=log)  # fmt: skip
        print(f"  raw bound (the network alone on the same minibatches, {model.n_epochs} epochs): {raw:,.0f} "
              f"agent-steps/s; the recipe at {fps / raw:.2f} of it", file=log)  # fmt: skip
    return [row]


def raw_bound(model, repeats: int) -> float:
    """Agent-steps/s of `model`'s network alone: its policy (after the timed run) trained, in plain torch, on the
    minibatches its rollout buffer holds (the last rollout, cut and padded as PPO's update cuts them), n_epochs
    passes per rollout, `repeats` times; each minibatch one forward (extractor, actor and critic LSTMs over whole
    sequences, heads), a loss touching logits and values, backward, gradient clipping and an Adam step."""
    policy = model.policy
    policy.set_training_mode(True)
    optimizer = torch.optim.Adam(policy.parameters(), lr=1e-5)
    batches = [(data.observations, data.lstm_states, data.episode_starts, data.actions.long().flatten(),
                data.mask > 1e-8) for data in map(_samples, model.rollout_buffer.get(model.batch_size))]  # fmt: skip

    def step(obs, states, starts, actions, mask) -> None:
        features = policy.features_extractor(obs)  # SearchCNN itself (SB3 would only cast to float)
        actor, _ = process_sequence(features, states.pi, starts, policy.lstm_actor)
        critic, _ = process_sequence(features, states.vf, starts, policy.lstm_critic)
        logits = policy.action_net(policy.mlp_extractor.forward_actor(actor))
        values = policy.value_net(policy.mlp_extractor.forward_critic(critic)).flatten()
        chosen = torch.log_softmax(logits, dim=1).gather(1, actions[:, None])[:, 0]
        loss = -chosen[mask].mean() + values[mask].square().mean()
        optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), model.max_grad_norm)
        optimizer.step()

    step(*batches[0])  # warm-up
    start = time.perf_counter()
    for _ in range(repeats * model.n_epochs):
        for batch in batches:
            step(*batch)
    return model.rollout_buffer.buffer_size * model.rollout_buffer.n_envs * repeats / (time.perf_counter() - start)


def _samples(item: tuple) -> tuple:
    """A minibatch's samples: the buffer's own, or the first of the (samples, labels) pairs the teacher term adds."""
    return item if hasattr(item, "observations") else item[0]
