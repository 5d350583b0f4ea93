# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The teacher's labels: target-greedy's kernel per agent (a benchmark)
#
# Microseconds per agent of `greedy_actions` (B's teacher, target-greedy with reach 2) over the three groups of
# B's recipe (`+experiment=term/b`: 16 worlds of 8 agents, 4 of 32, 1 of 128) after 20 random steps, at 1 and 2
# numba threads: the minimum and median of 7 trials of 20 calls per group. The figures of docs/lab/performance.md
# came from this script at c84ea00 and at its parent (`git checkout c84ea00~1 -- searchrl/controllers`), one sitting.
#
#     python analysis/label_speed.py

# %%
import time

import numpy as np
from hydra import compose, initialize_config_dir

from searchrl.controllers.greedy_kernels import greedy_actions
from searchrl.shared_schema import CONF_DIR
from searchrl.train.build import make_vec_env
from searchrl.train.plan import make_plan
from searchrl.train.schema import register_configs

register_configs()
with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
    cfg = compose(config_name="train", overrides=["+experiment=term/b"])
env = make_vec_env(make_plan(cfg), seed=0)  # TeacherLabels over the team mix
env.reset()
rng = np.random.default_rng(0)
for _ in range(20):
    env.step(rng.integers(0, 5, env.num_envs))

# %% [markdown]
# Each call labels every agent of a group; the figure is the wall time per agent labelled.

# %%
for threads in (1, 2):
    trials = []
    for _ in range(7):
        start = time.perf_counter()
        for _ in range(20):
            for group, teacher in zip(env.groups, env.teachers, strict=True):
                state = group.world.state
                out = np.zeros((state.n_worlds, state.n_agents), np.int64)
                greedy_actions(state.arrays(), teacher._params, teacher.remember(state), out, out, threads)
        trials.append((time.perf_counter() - start) / (20 * env.num_envs) * 1e6)
    print(f"threads {threads}: {min(trials):.2f} µs an agent (min of 7), median {sorted(trials)[3]:.2f}")
