"""Registries kept apart between tests: a module a test imports for its parts (an extension, a research script)
registers them for the test's process, and a worker runs several test files in turn."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from unittest import mock

from searchrl.controllers import registry
from searchrl.envs import parts, rewards
from searchrl.policies import networks
from searchrl.world import scenario


@contextlib.contextmanager
def isolated_registries(*packages: str) -> Iterator[None]:
    """Every registry by name as it was before the block, after it; the modules of `packages` (e.g. "analysis")
    are forgotten, so a later import registers their parts again. (Only those: the libraries a block imported
    the first time, numba's among them, cannot be imported twice.)"""
    tables = [registry.HEURISTICS, parts.PARTS, networks.NETWORKS, networks.CRITICS, rewards.REWARDS,
              *scenario.PARTS.values()]  # fmt: skip
    with contextlib.ExitStack() as stack:
        for table in tables:
            stack.enter_context(mock.patch.dict(table))
        stack.enter_context(mock.patch.object(registry, "TEACHERS", registry.TEACHERS))
        try:
            yield
        finally:
            for name in [m for m in sys.modules if m.split(".")[0] in packages]:
                del sys.modules[name]
