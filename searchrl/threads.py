"""The threads of a process, set once for both pools that do its work: torch's (the policy's forward and backward
passes) and numba's (the world's batch kernels, searchrl/world/parallel.py).

The two pools are two OpenMP runtimes (torch's bundled libgomp and numba's), and each one's workers spin a while
after every parallel region before they sleep. When the network runs on the same cores as the world, the world's
spinning workers take cycles from torch's update: B's recipe on two cores trained at 2,688 agent-steps/s with the
world on two threads against 2,926 with it on one (`python -m searchrl.bench train`), where the world is
5 % of the time. So the world gets every thread only where torch does not compute on the CPU (a policy on a GPU, a
heuristic without a network) and one thread where it does. Results do not depend on the world's count
(tests/test_threads.py).

The world package itself imports neither torch nor this module: the entry points (training, evaluation, render,
the benches) call `use_threads`.
"""

from __future__ import annotations

import numba
import torch


def use_threads(n: int, network_on_cpu: bool = True) -> int:
    """torch gets `n` threads (n >= 1); numba's world gets `n` (at most `numba.config.NUMBA_NUM_THREADS`, the pool
    it starts with: the machine's cores unless the NUMBA_NUM_THREADS environment variable says otherwise) when
    `network_on_cpu` is False, else 1 (module docstring). Returns numba's count."""
    torch.set_num_threads(n)
    world = 1 if network_on_cpu else min(n, int(numba.config.NUMBA_NUM_THREADS))
    numba.set_num_threads(world)
    return world
