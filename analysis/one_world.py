# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # One crowded world on every thread (a benchmark)
#
# A batch of one world (render, the PettingZoo env) cannot share worlds among threads; its step can share its merge,
# cut into blocks of agents (`searchrl.world.parallel.agent_blocks`). Here target-greedy (the teacher) plays one world
# of a Table 2 cell, model B's settings, on one thread, and its moves are replayed on fresh copies of that world at
# 1 numba thread and at all of them (`NUMBA_NUM_THREADS`: the cores) in turn, timing `step` alone: the best of 5
# replays' mean milliseconds per step. Once target-greedy's team has gathered, its merges scan large belief boxes
# every step, which random moves (`python -m searchrl.bench world`) never reach. The figures of docs/lab/performance.md
# came from this script at the commit that shares the merge (two cores) and, for its parent, with `git checkout
# <parent> -- searchrl/world`, one sitting.
#
#     python analysis/one_world.py

# %%
import time

import numba
import numpy as np

from searchrl.bench.world import case_config
from searchrl.controllers.registry import make_controller
from searchrl.world.engine import SearchWorld
from searchrl.world.step import step

CELLS = ((80, 128), (160, 256))  # (n, N)
THREADS = (1, numba.config.NUMBA_NUM_THREADS)
MAX_STEPS, REPLAYS = 150, 5


def moves(config, seed: int) -> list[np.ndarray]:
    """Target-greedy's (1, N) actions in world `seed` until its episode ends (or MAX_STEPS)."""
    numba.set_num_threads(1)
    world = SearchWorld(config, n_worlds=1, seed=seed)
    maps, vector = world.reset()
    controller = make_controller("greedy_target", config, seed=0)
    controller.reset(world.state, np.ones(1, bool))
    played = []
    for _ in range(MAX_STEPS):
        played.append(controller.act(world.state, maps, vector))
        transition = world.step(played[-1])
        maps, vector = transition.maps, transition.vector
        if transition.result.done.any():
            break
    return played


def replay_ms(config, seed: int, played: list[np.ndarray], threads: int) -> float:
    """Mean milliseconds of `step` over a replay of `played` in a fresh copy of world `seed` on `threads`."""
    numba.set_num_threads(threads)
    world = SearchWorld(config, n_worlds=1, seed=seed)
    world.reset()
    rng = np.random.default_rng(0)
    spent = 0.0
    for actions in played:
        start = time.perf_counter()
        step(config, world.state, actions, rng)
        spent += time.perf_counter() - start
    return 1e3 * spent / len(played)


# %% [markdown]
# Two worlds of each cell; the thread counts take turns replay by replay.

# %%
for n, n_agents in CELLS:
    config = case_config(n, n_agents)
    for seed in (3, 4):
        played = moves(config, seed)
        best = dict.fromkeys(THREADS, float("inf"))
        for _ in range(REPLAYS):  # in turn, so a busy neighbour weighs on each alike
            for threads in THREADS:
                best[threads] = min(best[threads], replay_ms(config, seed, played, threads))
        one, two = best[THREADS[0]], best[THREADS[-1]]
        print(
            f"n{n}_N{n_agents}, world {seed}, {len(played)} steps: {one:.2f} ms a step on 1 thread, "
            f"{two:.2f} on {THREADS[-1]}: {one / two:.2f}x"
        )
