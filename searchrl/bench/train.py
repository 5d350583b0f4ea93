"""SB3 training throughput on a device: RecurrentPPO on the VecEnv for a fixed number of updates, with the paper
network on model B's training scenarios, or a recipe (`--experiment`, e.g. one with the teacher term). Reports
agent-steps/s and the shares of the wall time: the world (the VecEnv's steps), acting (the policy's forward passes
during the rollout, with SB3's handling of them), the teacher's labels (runs with the teacher term), the rollout
buffer (filling it, returns and advantages, and forming the minibatches) and the update (the minibatches' forward,
backward and optimiser steps); what is left is SB3's bookkeeping.

In the same run, the raw bound: the recipe's network alone doing the work of each rollout, in plain torch with no
SB3 code in the timed loop: acting through the rollout's observations, then the recipe's epochs over its own
minibatches (taken from the rollout buffer before the clock starts), forward + backward + Adam step. It is measured
right after each update, on that update's rollout, outside the recipe's clock, and the policy's parameters are put
back after it: the recipe and its bound take turns through the run, so a neighbour that slows the machine for a
while slows both alike. The recipe cannot run faster than that; the ratio says how close it comes, and
`acting_ratio` and `update_ratio` how close its acting and its update come. On a GPU the clocks are read after
`torch.cuda.synchronize`.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TextIO

import numpy as np
import torch
from hydra import compose, initialize_config_dir

from searchrl.imitation.teacher_labels import TeacherLabels
from searchrl.policies.device import resolve_device
from searchrl.policies.recurrent import process_sequence
from searchrl.shared_schema import CONF_DIR
from searchrl.threads import use_threads
from searchrl.train.build import make_algorithm, make_vec_env
from searchrl.train.plan import make_plan
from searchrl.train.schema import register_configs


def _timed(fn: Callable, total: list[float], sync: Callable[[], None]) -> Callable:
    def timed(*args, **kwargs):
        start = time.perf_counter()
        out = fn(*args, **kwargs)
        sync()
        total[0] += time.perf_counter() - start
        return out

    return timed


def _timed_batches(get: Callable, total: list[float], sync: Callable[[], None]) -> Callable:
    """`get` of a rollout buffer whose time inside the generator (forming each minibatch) counts to `total`."""

    def timed(*args, **kwargs) -> Iterator:
        batches = get(*args, **kwargs)
        while True:
            start = time.perf_counter()
            item = next(batches, None)
            sync()
            total[0] += time.perf_counter() - start
            if item is None:
                return
            yield item

    return timed


def run(
    updates: int = 4,
    threads: int | None = None,
    network: str = "paper",
    experiment: str | None = None,
    device: str | None = None,
    machine: str | None = None,
    log: TextIO | None = None,
    overrides: Sequence[str] = (),
) -> list[dict]:
    """One run of `updates` rollouts (plus one warm-up rollout, not timed); `experiment` composes
    `+experiment=<name>` (its own model and network) instead of model B on the paper's recipe with `network`;
    `machine` composes `machine=<name>` (conf/machine/), whose threads and device `threads` and `device` replace;
    `overrides` are the training app's, after those (`critic=true_state`: the case's name carries them)."""
    given = list(overrides)
    overrides = composed_overrides(network, experiment, machine, given)
    overrides += [f"{key}={value}" for key, value in (("threads", threads), ("device", device)) if value is not None]
    register_configs()  # the training app's schemas, which the composed config names
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="train", overrides=overrides)
    # The few timed rollouts would all fall in a recipe's critic warm-up (its first rollouts, value-only updates):
    # time the updates the rest of the run makes.
    cfg.imitation.critic_warmup = 0
    plan = make_plan(cfg)
    threads, device = plan.settings.threads, str(resolve_device(plan.settings.device))  # `auto`: cpu or cuda
    use_threads(threads, network_on_cpu=torch.device(device).type == "cpu")
    sync = torch.cuda.synchronize if torch.device(device).type == "cuda" else lambda: None
    env = make_vec_env(plan, seed=0)
    base = env.venv if isinstance(env, TeacherLabels) else env
    spent = {part: [0.0] for part in ("world", "acting", "labels", "buffer", "update")}
    rollout_time, train_time, filling, batching = [0.0], [0.0], [0.0], [0.0]
    base.step_wait = _timed(base.step_wait, spent["world"], sync)
    if isinstance(env, TeacherLabels):
        env._label = _timed(env._label, spent["labels"], sync)
    model = make_algorithm(plan, env)
    buffer = model.rollout_buffer
    for name in ("add", "compute_returns_and_advantage"):
        setattr(buffer, name, _timed(getattr(buffer, name), filling, sync))
    buffer.get = _timed_batches(buffer.get, batching, sync)
    model.collect_rollouts = _timed(model.collect_rollouts, rollout_time, sync)
    model.train = _timed(model.train, train_time, sync)
    raw_acting, raw_update, bounding = [0.0], [0.0], [0.0]  # the raw bound's seconds, and the wall time it took
    model.train = _then_bound(model.train, model, sync, raw_acting, raw_update, bounding)
    rollout = plan.rollout
    model.learn(rollout)  # warm-up: numba cache, torch kernels
    for total in [*spent.values(), rollout_time, train_time, filling, batching, raw_acting, raw_update, bounding]:
        total[0] = 0.0
    start = time.perf_counter()
    model.learn(rollout * updates, reset_num_timesteps=False)
    sync()
    wall = time.perf_counter() - start - bounding[0]  # the recipe's own time
    spent["buffer"][0] = filling[0] + batching[0]
    spent["update"][0] = in_update = train_time[0] - batching[0]
    spent["acting"][0] = rollout_time[0] - spent["world"][0] - spent["labels"][0] - filling[0]
    fps = rollout * updates / wall
    acting_s, update_s = raw_acting[0] / updates, raw_update[0] / updates  # per rollout
    raw = rollout / (acting_s + update_s)
    name = f"recurrent_ppo_{network}_model_b_K{plan.settings.env.n_worlds}_N{plan.world.n_agents}"
    name = experiment.replace("/", "_") if experiment else name  # term/b -> term_b
    name += "".join(f"+{override.replace('/', '_')}" for override in given)  # term_b+critic=true_state
    slots = sum(k * world.n_agents for world, k in plan.groups)
    row = {
        "case": f"{name}_{machine or torch.device(device).type}_threads{threads}",
        "engine": "sb3",
        "device": device_name(device),
        "slots": slots,
        "batch_size": int(model.batch_size),
        "agent_steps_per_s": round(fps, 1),
        "raw_bound_agent_steps_per_s": round(raw, 1),
        "ratio_to_raw_bound": round(fps / raw, 3),
        "raw_acting_agent_steps_per_s": round(rollout / acting_s, 1),
        "raw_update_agent_steps_per_s": round(rollout / update_s, 1),
        "acting_ratio": round(acting_s * updates / spent["acting"][0], 3),
        "update_ratio": round(update_s * updates / in_update, 3),
    }
    row.update({f"{part}_share": round(total[0] / wall, 4) for part, total in spent.items()})
    if log:
        shares = ", ".join(f"{part} {100 * row[f'{part}_share']:.1f}%" for part in spent)
        print(
            f"{row['case']} on {row['device']}: {fps:,.0f} agent-steps/s over {updates} updates of {rollout} "
            f"agent-steps ({slots} slots, minibatch {model.batch_size}); wall time: {shares}, the rest SB3's "
            "bookkeeping",
            file=log,
        )
        print(
            f"  raw bound (the network alone, in plain torch, after each update: acting on its rollout, "
            f"{model.n_epochs} epochs on its minibatches): {raw:,.0f} agent-steps/s; the recipe at {fps / raw:.2f} "
            f"of it; its acting at {row['acting_ratio']:.2f} and its update at {row['update_ratio']:.2f} of theirs",
            file=log,
        )
    return [row]


def composed_overrides(network: str, experiment: str | None, machine: str | None, given: Sequence[str]) -> list[str]:
    """The training app's overrides of a case: the recipe (`+experiment=<name>`, else model B with `network`), the
    machine's settings, then the overrides `given`."""
    overrides = [f"+experiment={experiment}"] if experiment else ["+model=b", f"network={network}"]
    return overrides + ([f"machine={machine}"] if machine else []) + list(given)


def _then_bound(
    train: Callable, model, sync: Callable[[], None], acting: list[float], update: list[float], bounding: list[float]
) -> Callable:
    """`train` followed by the raw bound on the rollout it trained on: its acting and update seconds added to
    `acting` and `update`, the wall time the bound took to `bounding`; the policy's parameters, torch's random state
    and numpy's global one (the rollout buffer's minibatch order) are put back, so the recipe trains as it would
    alone."""

    def train_then_bound(*args, **kwargs):
        out = train(*args, **kwargs)
        start = time.perf_counter()
        saved, minibatch_order = copy.deepcopy(model.policy.state_dict()), np.random.get_state()  # noqa: NPY002
        with torch.random.fork_rng(devices=[model.device] if model.device.type == "cuda" else []):  # its samples
            acting[0] += raw_acting_seconds(model, sync)
            update[0] += raw_update_seconds(model, sync)
        model.policy.load_state_dict(saved)
        np.random.set_state(minibatch_order)  # noqa: NPY002 - the buffer's minibatches are drawn from it
        bounding[0] += time.perf_counter() - start
        return out

    return train_then_bound


@torch.no_grad()
def raw_acting_seconds(model, sync: Callable[[], None] = lambda: None) -> float:
    """Seconds `model`'s network alone takes to act through its last rollout, in plain torch: per step, one forward
    of every slot (the extractor, or the actor's and the critic's, the LSTMs one step on, heads) and a sample; the
    observations already on the device (the rollout buffer's), so neither the world nor SB3's handling of the
    tensors is in it."""
    policy, buffer = model.policy, model.rollout_buffer
    policy.set_training_mode(False)
    data, _ = next(_untimed_get(buffer)(None))  # every slot, sequence-major: (n_envs·n_steps, ...)
    steps = [
        {
            key: obs.reshape(buffer.n_envs, buffer.buffer_size, *obs.shape[1:])[:, t]
            for key, obs in data.observations.items()
        }
        for t in range(buffer.buffer_size)
    ]
    starts = data.episode_starts.reshape(buffer.n_envs, buffer.buffer_size)

    def rollout() -> None:
        pi, vf = data.lstm_states.pi, data.lstm_states.vf
        for t, obs in enumerate(steps):
            actor_features, critic_features = features(policy, obs)
            actor, pi = process_sequence(actor_features, pi, starts[:, t], policy.lstm_actor)
            critic, vf = process_sequence(critic_features, vf, starts[:, t], policy.lstm_critic)
            logits = policy.action_net(policy.mlp_extractor.forward_actor(actor))
            policy.value_net(policy.mlp_extractor.forward_critic(critic))
            torch.distributions.Categorical(logits=logits).sample()

    rollout()  # warm-up
    sync()
    start = time.perf_counter()
    rollout()
    sync()
    return time.perf_counter() - start


def raw_update_seconds(model, sync: Callable[[], None] = lambda: None) -> float:
    """Seconds `model`'s network alone takes to train on its last rollout, in plain torch: n_epochs passes over the
    minibatches its rollout buffer forms; each minibatch one forward (the extractor or both, actor and critic LSTMs
    over whole sequences, heads), a loss touching logits and values, backward, gradient clipping and an Adam step."""
    policy = model.policy
    policy.set_training_mode(True)
    optimizer = torch.optim.Adam(policy.parameters(), lr=1e-5)
    minibatches = _untimed_get(model.rollout_buffer)(model.batch_size)
    batches = [
        (data.observations, data.lstm_states, data.episode_starts, data.actions.long().flatten(), data.mask > 1e-8)
        for data in map(_samples, minibatches)
    ]

    def step(obs, states, starts, actions, mask) -> None:
        actor_features, critic_features = features(policy, obs)
        actor, _ = process_sequence(actor_features, states.pi, starts, policy.lstm_actor)
        critic, _ = process_sequence(critic_features, states.vf, starts, policy.lstm_critic)
        logits = policy.action_net(policy.mlp_extractor.forward_actor(actor))
        values = policy.value_net(policy.mlp_extractor.forward_critic(critic)).flatten()
        chosen = torch.log_softmax(logits, dim=1).gather(1, actions[:, None])[:, 0]
        loss = -chosen[mask].mean() + values[mask].square().mean()
        optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), model.max_grad_norm)
        optimizer.step()

    step(*batches[0])  # warm-up
    sync()
    start = time.perf_counter()
    for _ in range(model.n_epochs):
        for batch in batches:
            step(*batch)
    sync()
    return time.perf_counter() - start


def features(policy, obs: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
    """(the actor's features, the critic's) of a batch of observations, each (B, features_dim): one pass of the
    extractor when the policy shares it, else the critic's own extractor too (a critic such as `true_state`, whose
    cost is part of the network's). The extractors themselves: SB3 would only cast the observations to float."""
    actor = policy.pi_features_extractor(obs)
    return actor, (actor if policy.share_features_extractor else policy.vf_features_extractor(obs))


def _untimed_get(buffer) -> Callable:
    """The buffer's own `get`: `run` times the one set on the instance, whose time is the recipe's."""
    return type(buffer).get.__get__(buffer)


def device_name(device: str) -> str:
    """The card's name on a CUDA device, else the CPU's torch thread count."""
    if torch.device(device).type == "cuda":
        return torch.cuda.get_device_name(torch.device(device))
    return f"cpu ({torch.get_num_threads()} torch threads)"


def _samples(item: tuple) -> tuple:
    """A minibatch's samples: the buffer's own, or the first of the (samples, labels) pairs the teacher term adds."""
    return item if hasattr(item, "observations") else item[0]
