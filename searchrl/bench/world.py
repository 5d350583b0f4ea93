"""World throughput: agent-steps/s of the batched engine, at each numba thread count asked for, and of the plain
reference oracle (searchrl/world/oracle.py), on two cases, measured in one run so their ratios are meaningful on this
machine."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import TextIO

import numba
import numpy as np

from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.observe import observation_buffers, observe
from searchrl.world.reset import reset_worlds
from searchrl.world.state import WorldState, allocate
from searchrl.world.step import step

# (case name, world side n, agents N, worlds K); targets and m follow Table 2 for the side. The batch kernels share
# the worlds among the threads, so the one-world case measures the cost of threads it cannot use.
CASES = (("n40_N8_K64", 40, 8, 64), ("n160_N256_K1", 160, 256, 1))
_TABLE2 = {20: (4, 8), 40: (8, 16), 80: (16, 32), 160: (32, 64)}  # n -> (targets, distributions)
# Where a window's time goes. Stepping and observing are the world's parallel kernels (and the Python around them);
# drawing the actions and resetting finished worlds run in the calling thread whatever the thread count, so their
# share at one thread bounds what more threads can gain (Amdahl's law).
PARTS = ("actions", "step", "observe", "reset")
# The random actions are drawn this many steps at a time: the stand-in for a policy, whose actions come from its own
# threads or device, then costs the calling thread little, and the windows time the world.
ACTION_BLOCK = 64


def _load_oracle() -> tuple[Callable, Callable] | None:
    """The reference oracle's step and observe (searchrl/world/oracle.py)."""
    from searchrl.world.oracle import oracle_observe, oracle_step

    return oracle_step, oracle_observe


def max_threads() -> int:
    """The most numba threads this process can run (`numba.config.NUMBA_NUM_THREADS`: the cores, or the
    NUMBA_NUM_THREADS environment variable)."""
    return int(numba.config.NUMBA_NUM_THREADS)


def thread_counts(text: str) -> list[int]:
    """`--threads` of the world suite: "2" or "1,2" (each measured in the same run), as a list of ints."""
    try:
        return [int(part) for part in text.split(",")]
    except ValueError:
        raise ConfigError(f"--threads={text} is not allowed: thread counts separated by commas, e.g. 1,2") from None


def case_config(n: int, n_agents: int) -> WorldConfig:
    """Model B settings on a Table 2 cell (communication on, Φ = 5)."""
    targets, dists = _TABLE2[n]
    return WorldConfig(
        world_size=(n, n), n_targets=(targets, targets), n_distributions=(dists, dists), n_agents=n_agents
    )


def _steps(
    config: WorldConfig,
    state: WorldState,
    step_fn: Callable,
    observe_fn: Callable,
    rng: np.random.Generator,
    seconds: float,
    min_steps: int,
) -> tuple[float, dict[str, float]]:
    """Agent-steps/s of one window: step + observe + reset of finished worlds, random actions (drawn
    `ACTION_BLOCK` steps at a time); and the shares of the window's wall time (`PARTS`) spent drawing the actions,
    stepping, observing and resetting. Each part runs from the end of the one before, so the shares sum to 1: the
    loop's own bookkeeping counts with the actions."""
    n_worlds = state.n_worlds
    spent = dict.fromkeys(PARTS, 0.0)
    steps, start = 0, time.perf_counter()
    t0, block = start, np.empty(0, np.int64)
    while steps < min_steps or t0 - start < seconds:
        if steps % ACTION_BLOCK == 0:
            block = rng.integers(0, config.n_actions, size=(ACTION_BLOCK, n_worlds, config.n_agents))
        actions = block[steps % ACTION_BLOCK]
        t1 = time.perf_counter()
        result = step_fn(config, state, actions, rng)
        t2 = time.perf_counter()
        observe_fn(config, state)
        t3 = time.perf_counter()
        done = result.terminated | result.truncated
        if done.any():
            reset_worlds(config, state, done, rng)
        t4 = time.perf_counter()
        for part, took in zip(PARTS, (t1 - t0, t2 - t1, t3 - t2, t4 - t3), strict=True):
            spent[part] += took
        steps += 1
        t0 = t4
    wall = t0 - start
    return steps * n_worlds * config.n_agents / wall, {part: took / wall for part, took in spent.items()}


def measure(
    config: WorldConfig,
    n_worlds: int,
    step_fn: Callable,
    observe_fn: Callable,
    seconds: float,
    min_steps: int = 1,
    repeats: int = 3,
    threads: Sequence[int] = (0,),
) -> dict[int, tuple[float, dict[str, float]]]:
    """(agent-steps/s, the shares of its wall time by `PARTS`) of step + observe + reset of finished worlds, random
    actions, at each numba thread count of `threads` (0: leave numba's as it is), after one warm-up step at each.

    The best of `repeats` windows of `seconds / repeats` each is reported (as `timeit` does): on a shared
    2-core machine the slower windows measure the neighbours, not the engine. The thread counts take turns window
    by window, so a neighbour that comes and goes weighs on each alike.
    """
    rng = np.random.default_rng(0)
    state = allocate(config, n_worlds)
    reset_worlds(config, state, np.ones(n_worlds, bool), rng)
    # Clocks spread over an episode: worlds reset together would reset all at once every max_steps steps, and a
    # window shorter than that would hold all of those resets or none, at random; spread, each window resets its
    # share, as a long run does on average.
    state.t[:] = np.arange(n_worlds) * config.max_steps // n_worlds
    before = numba.get_num_threads()
    best: dict[int, tuple[float, dict[str, float]]] = {t: (0.0, {}) for t in threads}
    try:
        for t in threads:  # warm-up (numba compile or cache load, numba's threads started)
            numba.set_num_threads(t or before)
            step_fn(config, state, rng.integers(0, config.n_actions, size=(n_worlds, config.n_agents)), rng)
        for _ in range(repeats):
            for t in threads:
                numba.set_num_threads(t or before)
                window = _steps(config, state, step_fn, observe_fn, rng, seconds / repeats / len(threads), min_steps)
                best[t] = max(best[t], window, key=lambda speed_shares: speed_shares[0])
    finally:
        numba.set_num_threads(before)
    return best


def run(seconds: float = 3.0, threads: Sequence[int] | None = None, log: TextIO | None = None) -> list[dict]:
    """Measure every case with the engine at each of `threads` (numba thread counts; default numba's current one,
    all cores unless set) and once with the oracle; one row per (case, engine, threads). `seconds` is the budget of
    each case's batched measurement and of its oracle's."""
    threads = list(threads) if threads else [numba.get_num_threads()]
    oracle = _load_oracle()
    rows = []
    for name, n, n_agents, n_worlds in CASES:
        config = case_config(n, n_agents)
        buffers = observation_buffers(config, n_worlds)  # reused, as SearchWorld does
        speeds = measure(
            config, n_worlds, step, lambda c, s, b=buffers: observe(c, s, b), seconds, min_steps=20, threads=threads
        )
        first, first_shares = speeds[threads[0]]
        parts = []
        for t in threads:
            speed, shares = speeds[t]
            rows.append(
                {
                    "case": name,
                    "engine": "batched",
                    "threads": t,
                    "agent_steps_per_s": round(speed, 1),
                    **{f"{part}_share": round(share, 4) for part, share in shares.items()},
                }
            )
            scaling = f", {speed / first:.2f}x" if t != threads[0] else ""
            parts.append(f"{speed:>12,.0f} ({t} thread{'s' if t > 1 else ''}{scaling})")
        line = f"{name:>14}: batched {' '.join(parts)} agent-steps/s"
        serial = first_shares["actions"] + first_shares["reset"]
        line += f" | actions + resets {serial:.0%} at {threads[0]} thread{'s' if threads[0] > 1 else ''}"
        if oracle is not None:
            slow = measure(config, n_worlds, oracle[0], oracle[1], seconds, min_steps=1, repeats=1)[0][0]
            rows.append({"case": name, "engine": "oracle", "threads": 1, "agent_steps_per_s": round(slow, 1)})
            line += f" | oracle {slow:>10,.0f} | ratio {first / slow:>7.1f}x (threads={threads[0]})"
        if log:
            print(line, file=log, flush=True)
    if log:
        if oracle is None:
            print("oracle not found (tests/oracle.py): run from a source checkout for the ratio", file=log)
    return rows
