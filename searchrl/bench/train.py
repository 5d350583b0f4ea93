"""SB3 training throughput: RecurrentPPO on the VecEnv for a fixed number of updates, with the paper network on
model B's training scenarios, or a recipe (`--experiment`, e.g. one with the teacher term). Reports agent-steps/s
and where the wall time goes: the environment's steps, the teacher's labels (runs with the teacher term), the
updates (`train`); the rest is the policy acting during the rollout and SB3's bookkeeping."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TextIO

import torch
from hydra import compose, initialize_config_dir

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
    name = experiment or f"recurrent_ppo_{network}_model_b_K{cfg.env.n_worlds}_N{cfg.env.world.n_agents}"
    row = {"case": f"{name}_threads{threads}", "engine": "sb3", "agent_steps_per_s": round(fps, 1)}
    row.update({f"{part}_share": round(total[0] / wall, 4) for part, total in spent.items()})
    if log:
        shares = ", ".join(f"{part} {100 * row[f'{part}_share']:.1f}%" for part in spent)
        print(f"{row['case']}: {fps:,.0f} agent-steps/s over {updates} updates of {rollout} agent-steps; "
              f"wall time: {shares}, the rest acting and bookkeeping", file=log)  # fmt: skip
    return [row]
