"""Every shipped policy and every kept heuristic plays the recorded episodes of tests/golden/slice.parquet bit for
bit (tests/golden_slice.py made them): a refactor of the world, the controllers or the episode loop that changes an
episode fails here."""

from __future__ import annotations

import pandas as pd
import pytest
import torch

from tests.golden_slice import GOLDEN, golden_frame

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)


def test_shipped_controllers_replay_their_recorded_episodes():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        fresh = golden_frame()
    finally:
        torch.set_num_threads(threads)
    recorded = pd.read_parquet(GOLDEN)
    assert sorted(fresh["controller"].unique()) == sorted(recorded["controller"].unique())
    assert list(fresh.columns) == list(recorded.columns)
    pd.testing.assert_frame_equal(fresh, recorded, check_exact=True)
