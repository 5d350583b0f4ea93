"""The threads of a process: how many each pool gets, and how torch's OpenMP threads wait.

**How many** (`use_threads`), set once for both pools that do the work: torch's (the policy's forward and backward
passes) and numba's (the world's batch kernels, searchrl/world/parallel.py). The two pools are two OpenMP runtimes
(torch's bundled libgomp and numba's), and each one's workers spin a while after every parallel region before they
sleep. When the network runs on the same cores as the world, the world's spinning workers take cycles from torch's
update: B's recipe on two cores trained at 2,688 agent-steps/s with the world on two threads against 2,926 with it
on one (`python -m searchrl.bench train`), where the world is 5 % of the time. So the world gets every thread only
where torch does not compute on the CPU (a policy on a GPU, a heuristic without a network) and one thread where it
does. Results do not depend on the world's count (tests/test_threads.py).

**When**: before torch's first parallel work. torch's OpenMP pool starts with the thread count of that moment (every
core by default) and keeps its workers when `set_num_threads` lowers the count later; beside a busy core those
workers, spinning, took the core the work needed. A policy's evaluation on one thread whose actor was built before
the count was set ran at 243 agent-steps/s beside another job on a two-core machine, against 15,101 with the count
set first (`python -m searchrl.bench eval --checkpoint runs/reference/term/b/model.zip --maps 2 --threads 1 --cells
n40_N2,n80_N8,n80_N32,n160_N64`), and at 5,053 with PASSIVE waiting (two of those cells). So the apps and benches
call `use_threads` before they load a checkpoint.

**How they wait** (`set_wait_policy`), set by the Hydra apps' entry points before torch loads (libgomp reads
OMP_WAIT_POLICY once, when it starts). A waiting thread spins briefly, then sleeps (libgomp's default), or sleeps at
once (PASSIVE). PPO's update is many small parallel regions: on two idle cores B's shipped recipe trained at 3,760
agent-steps/s with the default against 2,619 with PASSIVE (`python -m searchrl.bench train`). Where the cores are
shared, spinning steals time from the working threads (1,107 against 1,959 with the other core busy; a tiny run in
a parallel sweep once slowed 20x). So a multirun (Hydra's -m: its jobs may share the cores) sleeps and a single run
spins briefly; an OMP_WAIT_POLICY already set is left alone.

Importing this module loads neither torch nor numba (`use_threads` does), and importing the world or the package
sets nothing: the world package imports neither torch nor this module. The Hydra apps' entry points call
`set_wait_policy`; training, evaluation and the benches call `use_threads`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

MULTIRUN_FLAGS = ("-m", "--multirun", "hydra.mode=MULTIRUN")


def set_wait_policy(argv: Sequence[str]) -> None:
    """PASSIVE for a multirun's command line `argv`, unless OMP_WAIT_POLICY is set already."""
    if any(arg in MULTIRUN_FLAGS for arg in argv):
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def use_threads(n: int, network_on_cpu: bool = True) -> int:
    """torch gets `n` threads (n >= 1); numba's world gets `n` (at most `numba.config.NUMBA_NUM_THREADS`, the pool
    it starts with: the machine's cores unless the NUMBA_NUM_THREADS environment variable says otherwise) when
    `network_on_cpu` is False, else 1 (module docstring). Returns numba's count."""
    import numba  # here, not at the top: the entry points set the wait policy before torch loads
    import torch

    torch.set_num_threads(n)
    world = 1 if network_on_cpu else min(n, int(numba.config.NUMBA_NUM_THREADS))
    numba.set_num_threads(world)
    return world
