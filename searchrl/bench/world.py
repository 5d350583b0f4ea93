"""World throughput: agent-steps/s of the batched engine and of the plain reference oracle (tests/oracle.py),
on two cases, measured in one run so their ratio is meaningful on this machine."""

from __future__ import annotations

import importlib.util
import time
from collections.abc import Callable
from pathlib import Path
from typing import TextIO

import numpy as np

from searchrl.world.config import WorldConfig
from searchrl.world.observe import observation_buffers, observe
from searchrl.world.reset import reset_worlds
from searchrl.world.state import allocate
from searchrl.world.step import step

# (case name, world side n, agents N, worlds K); targets and m follow Table 2 for the side.
CASES = (("n40_N8_K64", 40, 8, 64), ("n160_N256_K1", 160, 256, 1))
_TABLE2 = {20: (4, 8), 40: (8, 16), 80: (16, 32), 160: (32, 64)}  # n -> (targets, distributions)


def _load_oracle() -> tuple[Callable, Callable] | None:
    """The oracle lives in tests/ (it is a test artefact); available when running from a checkout."""
    path = Path(__file__).resolve().parents[2] / "tests" / "oracle.py"
    if not path.exists():
        return None
    spec = importlib.util.spec_from_file_location("searchrl_test_oracle", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.oracle_step, module.oracle_observe


def case_config(n: int, n_agents: int) -> WorldConfig:
    """Model B settings on a Table 2 cell (communication on, Φ = 5)."""
    targets, dists = _TABLE2[n]
    return WorldConfig(world_size=(n, n), n_targets=(targets, targets), n_distributions=(dists, dists),
                       n_agents=n_agents)  # fmt: skip


def measure(config: WorldConfig, n_worlds: int, step_fn: Callable, observe_fn: Callable, seconds: float,
            min_steps: int = 1, repeats: int = 3) -> float:  # fmt: skip
    """Agent-steps/s of step + observe + reset of finished worlds, random actions, after one warm-up step.

    The best of `repeats` windows of `seconds / repeats` each is reported (as `timeit` does): on a shared
    2-core machine the slower windows measure the neighbours, not the engine.
    """
    rng = np.random.default_rng(0)
    state = allocate(config, n_worlds)
    reset_worlds(config, state, np.ones(n_worlds, bool), rng)
    actions = rng.integers(0, config.n_actions, size=(n_worlds, config.n_agents))
    step_fn(config, state, actions, rng)  # warm-up (numba compile or cache load)
    best = 0.0
    for _ in range(repeats):
        steps, start = 0, time.perf_counter()
        while steps < min_steps or time.perf_counter() - start < seconds / repeats:
            actions = rng.integers(0, config.n_actions, size=(n_worlds, config.n_agents))
            result = step_fn(config, state, actions, rng)
            observe_fn(config, state)
            done = result.terminated | result.truncated
            if done.any():
                reset_worlds(config, state, done, rng)
            steps += 1
        best = max(best, steps * n_worlds * config.n_agents / (time.perf_counter() - start))
    return best


def run(seconds: float = 3.0, log: TextIO | None = None) -> list[dict]:
    """Measure every case with the engine and the oracle; returns one row per (case, engine)."""
    oracle = _load_oracle()
    rows = []
    for name, n, n_agents, n_worlds in CASES:
        config = case_config(n, n_agents)
        buffers = observation_buffers(config, n_worlds)  # reused, as SearchWorld does
        engine = measure(config, n_worlds, step, lambda c, s, b=buffers: observe(c, s, b), seconds, min_steps=20)
        rows.append({"case": name, "engine": "batched", "agent_steps_per_s": round(engine, 1)})
        line = f"{name:>14}: batched {engine:>12,.0f} agent-steps/s"
        if oracle is not None:
            slow = measure(config, n_worlds, oracle[0], oracle[1], seconds, min_steps=1, repeats=1)
            rows.append({"case": name, "engine": "oracle", "agent_steps_per_s": round(slow, 1)})
            line += f" | oracle {slow:>10,.0f} | ratio {engine / slow:>7.1f}x"
        if log:
            print(line, file=log, flush=True)
    if log:
        if oracle is None:
            print("oracle not found (tests/oracle.py): run from a source checkout for the ratio", file=log)
    return rows
