"""searchrl: decentralized multi-agent search with deep reinforcement learning."""

from __future__ import annotations

import os
import sys
from typing import TYPE_CHECKING, Any

# How torch's OpenMP threads wait, decided here because libgomp reads OMP_WAIT_POLICY once, when torch loads it, and
# every searchrl entry point imports this package first. A waiting thread spins briefly, then sleeps (libgomp's
# default), or sleeps at once (PASSIVE). PPO's update is many small parallel regions: on two idle cores B's shipped
# recipe trained at 3,760 agent-steps/s with the default against 2,619 with PASSIVE (docs/performance.md). Where
# the cores are shared, spinning steals time from the working threads (1,107 against 1,959 with the other core
# busy; a tiny run in a parallel sweep once slowed 20x). So a multirun (Hydra's -m: its jobs may share the cores)
# sleeps and a single run spins briefly; an OMP_WAIT_POLICY already set is left alone.
MULTIRUN_FLAGS = ("-m", "--multirun", "hydra.mode=MULTIRUN")
if any(arg in MULTIRUN_FLAGS for arg in sys.argv):
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

if TYPE_CHECKING:
    from searchrl.envs.parallel_env import SearchParallelEnv


def parallel_env(config: Any = None, render_mode: str | None = None, scenario: Any = None, **world: Any
                 ) -> SearchParallelEnv:  # fmt: skip
    """A PettingZoo ParallelEnv over one search world: pass a `WorldConfig`, or its fields as keywords; `scenario` a
    `searchrl.world.scenario.Scenario` or its mapping ({"obstacles": {"kind": "iid", "density": 0.2}}), the paper's
    when None."""
    from searchrl.envs.parallel_env import SearchParallelEnv
    from searchrl.world.config import WorldConfig
    from searchrl.world.scenario import Scenario

    if config is not None and world:
        raise TypeError("pass either a WorldConfig or its fields as keywords, not both")
    scenario = scenario if isinstance(scenario, Scenario) else Scenario.from_dict(scenario)
    return SearchParallelEnv(config if config is not None else WorldConfig(**world), render_mode, scenario)
