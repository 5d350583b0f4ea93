"""Older folders read as the current version: each change to what a run's config.yaml, an evaluation's record or a
cell's rows hold is one upgrade here, applied once on read, so no reader keeps branches for the versions before it.

An upgrade takes a record in an older form and returns it in the next; `upgrade_run_config` and `upgrade_cell`
apply every upgrade that applies (each checks the form it upgrades, so a current record passes unchanged), and
`EVALUATION_RECORD_ADDED` holds what an evaluation record made before a setting existed ran with. Each has a test
with a record of the form it upgrades (tests/test_migrations.py).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pandas as pd

from searchrl.world.scenario import PAPER

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


# Settings an evaluation record (evaluation.yaml, a cell's attrs) gained after folders were made, with the value
# those folders ran with: scenarios (the paper's), grid.agents (every team size), device (the CPU), inference
# (torch). A record that lacks one matches a run at that value (searchrl/evaluate/record.py `option_defaults`).
EVALUATION_RECORD_ADDED: dict[str, Any] = {"scenario": PAPER.to_dict(), "grid": {"agents": None}}
POLICY_RECORD_ADDED: dict[str, Any] = {"device": "cpu", "inference": "torch"}


def upgrade_cell(frame: pd.DataFrame, world_label: Callable[[], str]) -> pd.DataFrame:
    """A cell's rows in the current form: a cell made before the `world` column gets its folder's sensing label
    (`world_label()`, read only then), one made before scenarios existed the paper's."""
    if "world" not in frame:
        frame.insert(2, "world", world_label())
    if "scenario" not in frame:
        frame.insert(3, "scenario", PAPER.label)
    return frame
