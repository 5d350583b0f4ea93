# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Where one thread's world time goes (a benchmark)
#
# The loop of `python -m searchrl.bench world` (random actions, step, observation, resets of finished worlds; model
# B's settings) at (n, N, K) = (40, 8, 64) on one numba thread, each call timed: the parallel kernels (`step_worlds`,
# `observe_into`, and a reset's maps, `_densities` and `_mixture_maps`), the Python around the step's two, the
# resets and the action draws, as shares of the wall time over 2,000 steps, three runs. Only the kernels share
# their work among threads; the rest runs in the calling thread, so its share s bounds two threads at
# 1 / (s + (1 − s) / 2) (Amdahl's law).
# The figures of docs/lab/performance.md came from this script at 3ef57a5 (two sittings), c04606f, 0854221 (two
# sittings), 7b5cc23, ba06ae3, ca4d35b and 01d0378.
#
#     python analysis/world_profile.py

# %%
import time

import numba
import numpy as np

from searchrl.bench.world import ACTION_BLOCK, case_config
from searchrl.world import maps as maps_module
from searchrl.world import observe as observe_module
from searchrl.world import step as step_module
from searchrl.world.observe import observe
from searchrl.world.reset import reset_worlds
from searchrl.world.state import allocate

KERNELS = {
    "step_worlds": step_module,
    "observe_into": observe_module,
    "_densities": maps_module,
    "_mixture_maps": maps_module,
}
spent: dict[str, float] = dict.fromkeys(KERNELS, 0.0)


def timed(name, kernel):
    def call(*args):
        start = time.perf_counter()
        kernel(*args)
        spent[name] += time.perf_counter() - start

    return call


for name, module in KERNELS.items():  # the wrappers look the kernels up in their modules at each call
    setattr(module, name, timed(name, getattr(module, name)))

# %% [markdown]
# The worlds' clocks are spread over an episode, as the bench spreads them, so each stretch of steps resets its
# share of the worlds; the random actions are drawn `ACTION_BLOCK` steps at a time, as the bench draws them (up to
# 479566b both drew them one step at a time).

# %%
numba.set_num_threads(1)
config, n_worlds, steps = case_config(40, 8), 64, 2_000
for run in range(3):
    rng = np.random.default_rng(run)
    state = allocate(config, n_worlds)
    reset_worlds(config, state, np.ones(n_worlds, bool), rng)
    state.t[:] = np.arange(n_worlds) * config.max_steps // n_worlds
    parts = dict.fromkeys(("actions", "step + observe", "resets"), 0.0)
    for warm_up in (True, False):
        spent.update(dict.fromkeys(KERNELS, 0.0))
        parts.update(dict.fromkeys(parts, 0.0))
        begin = time.perf_counter()
        for i in range(50 if warm_up else steps):
            t0 = time.perf_counter()
            if i % ACTION_BLOCK == 0:  # as the bench draws them
                block = rng.integers(0, config.n_actions, size=(ACTION_BLOCK, n_worlds, config.n_agents))
            actions = block[i % ACTION_BLOCK]
            t1 = time.perf_counter()
            result = step_module.step(config, state, actions, rng)
            observe(config, state)
            t2 = time.perf_counter()
            if result.done.any():
                reset_worlds(config, state, result.done, rng)
            t3 = time.perf_counter()
            parts["actions"] += t1 - t0
            parts["step + observe"] += t2 - t1
            parts["resets"] += t3 - t2
        wall = time.perf_counter() - begin
    kernels, maps = sum(spent.values()), spent["_densities"] + spent["_mixture_maps"]
    serial = 1 - kernels / wall
    print(
        f"run {run}: {steps * n_worlds * config.n_agents / wall:,.0f} agent-steps/s; kernels {kernels / wall:.1%}, "
        f"Python around the step's {(parts['step + observe'] - kernels + maps) / wall:.1%}, resets "
        f"{parts['resets'] / wall:.1%} (their maps' kernels {maps / wall:.1%}), "
        f"actions {parts['actions'] / wall:.1%}; "
        f"outside the kernels {serial:.1%}: two threads at most {1 / (serial + (1 - serial) / 2):.2f}x"
    )
