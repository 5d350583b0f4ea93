"""How torch's OpenMP threads wait, set by the Hydra apps' entry points before torch loads (libgomp reads
OMP_WAIT_POLICY once, when it starts).

A waiting thread spins briefly, then sleeps (libgomp's default), or sleeps at once (PASSIVE). PPO's update is many
small parallel regions: on two idle cores B's shipped recipe trained at 3,760 agent-steps/s with the default
against 2,619 with PASSIVE (`python -m searchrl.bench train`). Where the cores are shared, spinning steals time from
the working threads (1,107 against 1,959 with the other core busy; a tiny run in a parallel sweep once slowed 20x). So a
multirun (Hydra's -m: its jobs may share the cores) sleeps and a single run spins briefly; an OMP_WAIT_POLICY
already set is left alone. Importing the world or the package sets nothing.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

MULTIRUN_FLAGS = ("-m", "--multirun", "hydra.mode=MULTIRUN")


def set_wait_policy(argv: Sequence[str]) -> None:
    """PASSIVE for a multirun's command line `argv`, unless OMP_WAIT_POLICY is set already."""
    if any(arg in MULTIRUN_FLAGS for arg in argv):
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
