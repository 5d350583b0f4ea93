"""Older folders read as the current version: each change to what a run's config.yaml holds is one upgrade here,
applied once on read, so no reader keeps branches for the versions before it.

An upgrade takes the plain mapping of a record and returns it in the next form; `upgrade_run_config` applies every
upgrade that applies (each checks the form it upgrades, so a current record passes through unchanged). Each has a
test with a record of the form it upgrades (tests/test_migrations.py).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

Record = dict[str, Any]


def reward_node(record: Record) -> Record:
    """`reward: <name>` (a run made before rewards took settings) -> `reward: {name: <name>}`."""
    if isinstance(record.get("reward"), str):
        record = {**record, "reward": {"name": record["reward"]}}
    return record


RUN_CONFIG_UPGRADES: tuple[Callable[[Record], Record], ...] = (reward_node,)


def upgrade_run_config(record: Record) -> Record:
    """A run's config.yaml (a plain mapping) in the current form."""
    for upgrade in RUN_CONFIG_UPGRADES:
        record = upgrade(record)
    return record
