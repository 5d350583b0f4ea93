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


def _ours(module: str, packages: tuple[str, ...]) -> bool:
    """Whether `module` is one of `packages` or below one (a package may be dotted: tests.extension_example)."""
    return any(module == p or module.startswith(f"{p}.") for p in packages)


@contextlib.contextmanager
def isolated_registries(*packages: str) -> Iterator[None]:
    """Inside the block the modules of `packages` (e.g. "analysis") and the parts they registered are gone, so an
    import registers them afresh; after it, every registry and those modules are as they were before. (Only those
    packages: the libraries a block imported the first time, numba's among them, cannot be imported twice.)"""
    tables = [registry.HEURISTICS, parts.PARTS, networks.NETWORKS, networks.CRITICS, rewards.REWARDS,
              *scenario.PARTS.values()]  # fmt: skip
    before = {name: module for name, module in sys.modules.items() if _ours(name, packages)}
    with contextlib.ExitStack() as stack:
        for table in tables:
            stack.enter_context(mock.patch.dict(table))
            for name, part in list(table.items()):
                if _ours(getattr(getattr(part, "cls", part), "__module__", ""), packages):
                    del table[name]
        for name in before:
            del sys.modules[name]
        try:
            yield
        finally:
            for name in [m for m in sys.modules if _ours(m, packages)]:
                del sys.modules[name]
            sys.modules.update(before)
