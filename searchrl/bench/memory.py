"""Resident memory of the largest evaluation world (n=160, N=256, K=1), measured in this fresh process."""

from __future__ import annotations

import resource
from typing import TextIO

import numpy as np

from searchrl.bench.world import case_config
from searchrl.world.engine import SearchWorld

LIMIT_MB = 500.0


def run(log: TextIO | None = None) -> list[dict]:
    """Build the world, run 64 random steps, report peak RSS (MB) of the process and the state's array bytes."""
    config = case_config(160, 256)
    world = SearchWorld(config, n_worlds=1, seed=0)
    world.reset()
    rng = np.random.default_rng(1)
    for _ in range(64):
        world.step(rng.integers(0, config.n_actions, size=(1, config.n_agents)))
    state_mb = sum(v.nbytes for v in vars(world.state).values() if isinstance(v, np.ndarray)) / 2**20
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux reports KiB
    if log:
        print(
            f"n160_N256_K1: peak resident {peak_mb:,.0f} MB (limit {LIMIT_MB:.0f}), world arrays "
            f"{state_mb:,.0f} MB, ratio to limit {peak_mb / LIMIT_MB:.2f}",
            file=log,
        )
    return [
        {"case": "n160_N256_K1", "engine": "batched", "peak_rss_mb": round(peak_mb, 1), "state_mb": round(state_mb, 1)}
    ]
