"""How the world's batch kernels share K worlds among numba's threads.

A batch kernel (`step.step_worlds`, `observe.observe_into`, `seen.remember_sightings`) splits its worlds into
`chunk_count` contiguous chunks, one per numba thread, and runs them in a `prange` loop; chunk c works the worlds
of `chunk_span(c, ...)` one after the other, with scratch slot c where it needs scratch. What a world's step does
depends on that world's rows alone, its random draws come in (K, ...) arrays drawn before the call, and nothing
is summed across worlds, so neither the number of threads nor which thread steps a world changes a bit of the
result (tests/test_threads.py). One chunk (one thread, or one world) runs in the calling thread, outside any
parallel region, so a single thread costs nothing over a plain loop. A reset's kernels cut their own rows the same
way: `maps._densities` its (Gaussian, grid row) rows, `maps._mixture_maps` its grid rows and `reset._write_world`
its agents' beliefs (tests/test_threads.py, and tests/test_generation.py for the maps alone).

A batch of fewer worlds than threads (one world: render, the PettingZoo env, `bench world`'s (160, 256, 1)) would
leave threads idle, and a crowded world's merge is most of its step. So `step.step_worlds` then also cuts each
world's merge into blocks of agents (`agent_blocks`): its first pass reads the beliefs and its second writes each
agent's own, so within a pass the blocks are independent, and the step is the same bit for bit. `observe_into`
cuts such worlds' agents into blocks the same way (each agent's observation is its own rows).

The threads are numba's: `numba.set_num_threads` (or `searchrl.threads.use_threads`) sets how many, up to
`numba.config.NUMBA_NUM_THREADS` (the cores, or the NUMBA_NUM_THREADS environment variable).
"""

from __future__ import annotations

import os

import numba
from numba import njit

from searchrl.world.kernels import CACHE


# The threading layer that runs the prange loops is numba's default choice: TBB where the tbb package is installed,
# else OpenMP, else numba's own workqueue (NUMBA_THREADING_LAYER picks one). Workqueue is the last resort, not a
# choice: its idle workers and its waiting caller poll with naps that double up to 20 ms, so a region of about a
# millisecond (a step of 64 worlds) waits about as long as it works, and 2 threads were no faster than 1 on an idle
# 16-core machine. GNU OpenMP (pip's numba without tbb) wakes its spinning workers at once but is not fork-safe:
# numba kills a forked child that opens a parallel region after its parent did. So a child forked after the
# parent's OpenMP threads started steps its worlds on one thread, in the calling thread (`chunk_count`), and never
# opens one. Hydra's multirun launchers start their jobs as new processes (joblib's loky executes a fresh
# interpreter; submitit runs a command), not as forks. OpenMP's workers wait as OMP_WAIT_POLICY says
# (searchrl/threads.py, set by the apps: in a multirun they sleep at once).
def _one_thread_after_fork() -> None:
    """In a child forked from a process whose OpenMP threads started, run the world's kernels in one thread."""
    try:
        layer = numba.threading_layer()
    except ValueError:  # no threads started before the fork: the child chooses and starts its own
        return
    if layer == "omp":
        numba.set_num_threads(1)


os.register_at_fork(after_in_child=_one_thread_after_fork)


def world_threads() -> int:
    """numba's threads for the calling thread (`numba.get_num_threads()`), what a batch kernel is told to use.

    Read in Python and passed in: called inside a compiled function, numba's get_num_threads is a ctypes pointer
    that keeps the function from being cached."""
    return numba.get_num_threads()


@njit(cache=CACHE, inline="always")
def chunk_count(n_worlds, slots, threads):
    """How many chunks to split n_worlds worlds into: one per thread (`threads`, `world_threads()`), at most one
    per world and per scratch slot (`slots`), at least one."""
    return max(1, min(n_worlds, slots, threads))


@njit(cache=CACHE, inline="always")
def chunk_span(chunk, n_chunks, first, stop):
    """(start, end): the worlds start..end-1 of chunk `chunk` when first..stop-1 is cut into n_chunks contiguous
    chunks whose sizes differ by at most one."""
    n = stop - first
    return first + chunk * n // n_chunks, first + (chunk + 1) * n // n_chunks


@njit(cache=CACHE, inline="always")
def agent_blocks(n_worlds, n_agents, threads, least):
    """Into how many blocks of agents to cut each world of a batch: enough that the worlds' blocks keep `threads`
    threads busy when there are fewer worlds than threads, each block at least `least` agents (a smaller block
    costs more to hand to a thread than its work); 1 (whole worlds) otherwise."""
    if n_worlds >= threads:
        return 1
    return max(1, min(-(-threads // n_worlds), n_agents // least))


@njit(cache=CACHE, inline="always")
def block_span(job, blocks, n_agents):
    """(world, start, end): job `job` of a batch cut into `blocks` blocks of agents a world (`agent_blocks`) works
    agents start..end-1 of that world; jobs 0..K·blocks-1 cover every agent of every world once."""
    first, stop = chunk_span(job % blocks, blocks, 0, n_agents)
    return job // blocks, first, stop
