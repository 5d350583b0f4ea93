# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A cold start: what numba compiles (a benchmark)
#
# The world's kernels are compiled on their first call and cached next to their source (`searchrl/world/kernels.py`),
# so a fresh install, a new numba or an edited kernel pays the compile once. Here a child process, given an empty
# cache (`NUMBA_CACHE_DIR`), runs what a new user's first commands run: four one-cell evaluations (surfing,
# target-greedy, path-greedy on walls, the shipped `term/b` policy: steps, resets, observations, the rules' kernels)
# and the world alone at two threads, one world of 64 agents (its merge and observation shared among the threads)
# and three worlds. numba's compile events give each function's own compile time (its callees' taken out) and
# how many argument types it was compiled for. The figures of docs/lab/performance.md came from this script at the
# commit that gave every compiled call one signature and, for its parent, with `git checkout <parent> -- searchrl`,
# one sitting.
#
#     python analysis/compile_time.py

# %%
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter


def child() -> None:
    """The workload, in a process whose numba cache is empty; prints one JSON line."""
    import numba
    from numba.core import event

    own, stack = Counter(), []

    class Timer(event.Listener):
        def on_start(self, e):
            stack.append([time.perf_counter(), 0.0])

        def on_end(self, e):
            start, callees = stack.pop()
            took = time.perf_counter() - start
            f = e.data["dispatcher"].py_func
            own[f"{f.__module__}.{f.__qualname__}"] += took - callees
            if stack:
                stack[-1][1] += took

    event.register("numba:compile", Timer())
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    began = time.perf_counter()
    from hydra import compose, initialize_config_dir

    from searchrl.bench.world import case_config, measure
    from searchrl.evaluate.app import evaluate
    from searchrl.shared_schema import CONF_DIR
    from searchrl.world.observe import observe
    from searchrl.world.step import step

    cell = [
        "grid.world_sizes=[20]",
        "grid.n_targets=[4]",
        "grid.n_distributions=[8]",
        "grid.max_agents=[2]",
        "grid.maps_per_cell=2",
        "grid.repeats=1",
        "progress_bar=false",
        "threads=2",
    ]
    runs = (
        ["controller=surfing"],
        ["controller=greedy_target"],
        ["controller=path_greedy", "scenario=walls"],
        ["checkpoint=runs/reference/term/b/model.zip"],
    )
    for overrides in runs:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            config = compose(config_name="evaluate", overrides=[*cell, f"out_dir={tempfile.mkdtemp()}", *overrides])
        evaluate(config, overrides)
    for n, n_agents, n_worlds in ((40, 64, 1), (20, 8, 3)):
        measure(case_config(n, n_agents), n_worlds, step, observe, 0.2, repeats=1, threads=(2,))
    signatures = {}
    for name, module in list(sys.modules.items()):
        for obj in vars(module).values() if name.startswith("searchrl") else ():
            if isinstance(obj, numba.core.registry.CPUDispatcher) and obj.py_func.__module__ == name:
                signatures[f"{name}.{obj.py_func.__qualname__}"] = len(obj.signatures)
    print(
        json.dumps(
            {
                "wall_s": time.perf_counter() - began,
                "compile_s": sum(own.values()),
                "own_s": dict(own.most_common(5)),
                "signatures": signatures,
            }
        )
    )


# %% [markdown]
# The parent starts the child with an empty cache and reports.

# %%
if __name__ == "__main__" and "--child" in sys.argv:
    child()
elif __name__ == "__main__":
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        done = subprocess.run(
            [sys.executable, __file__, "--child"], env=env, capture_output=True, text=True, check=True
        )
    report = json.loads(done.stdout.strip().splitlines()[-1])
    again = {name: n for name, n in report["signatures"].items() if n > 1}
    print(
        f"cold start: {report['wall_s']:.1f} s, of which compiling {report['compile_s']:.1f} s; "
        f"{len(report['signatures'])} compiled functions, {len(again)} of them for more than one signature"
    )
    for name, n in sorted(again.items()):
        print(f"  {name}: {n} signatures")
    own = ", ".join(f"{name.split('.')[-1]} {s:.1f} s" for name, s in report["own_s"].items())
    print("most compile time of its own:", own)
