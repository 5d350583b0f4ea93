"""SB3 training throughput: RecurrentPPO with the paper network on the VecEnv (model B, training scenarios),
for a fixed number of updates; reports agent-steps/s and the share of wall time spent in the environment."""

from __future__ import annotations

import time
from typing import TextIO

import torch
from hydra import compose, initialize_config_dir

from searchrl.train.__main__ import CONF_DIR
from searchrl.train.build import make_algorithm, make_vec_env


def run(updates: int = 4, threads: int = 2, network: str = "paper", log: TextIO | None = None) -> list[dict]:
    """One RecurrentPPO run of `updates` rollouts (plus one warm-up rollout, not timed)."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="train", overrides=["+model=b", f"network={network}", f"threads={threads}"])
    torch.set_num_threads(threads)
    env = make_vec_env(cfg, seed=0)
    env_time = [0.0]
    step_wait = env.step_wait

    def timed_step_wait():
        start = time.perf_counter()
        out = step_wait()
        env_time[0] += time.perf_counter() - start
        return out

    env.step_wait = timed_step_wait
    model = make_algorithm(cfg, env, tensorboard_log=None)
    rollout = model.n_steps * env.num_envs
    model.learn(rollout)  # warm-up: numba cache, torch kernels
    env_time[0] = 0.0
    start = time.perf_counter()
    model.learn(rollout * updates, reset_num_timesteps=False)
    wall = time.perf_counter() - start
    fps = rollout * updates / wall
    row = {
        "case": f"recurrent_ppo_{network}_model_b_K{cfg.env.n_worlds}_N{cfg.env.world.n_agents}_threads{threads}",
        "engine": "sb3",
        "agent_steps_per_s": round(fps, 1),
        "env_share": round(env_time[0] / wall, 4),
    }
    if log:
        print(
            f"{row['case']}: {fps:,.0f} agent-steps/s over {updates} updates of {rollout} agent-steps; "
            f"environment {100 * row['env_share']:.1f}% of wall time",
            file=log,
        )
    return [row]
