"""Frozen suites need frozen worlds: every scenario of the suites in conf/suite/ (and a few more settings of each
part: other corridors and rooms, the shift's distance, a prior family among walls) draws, from a seed, the worlds
recorded in tests/golden/suite_worlds.json: the same walls, prior maps, targets and start cells. A change to a
generator that moves any draw fails here; left unseen it would change every suite's worlds, and every comparison
against results made before it. `python -m tests.test_frozen_worlds` records the digests again: for a deliberate
change only, with the suites' results made again."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from searchrl.evaluate.suite import suite_scenarios
from searchrl.shared_schema import group_option
from searchrl.world.config import WorldConfig
from searchrl.world.reset import reset_worlds
from searchrl.world.scenario import Scenario
from searchrl.world.state import allocate
from tests.test_generators import _digest

GOLDEN = Path(__file__).resolve().parent / "golden" / "suite_worlds.json"
CONFIG = WorldConfig(world_size=(20, 33), n_agents=6, n_targets=(4, 12), n_distributions=(3, 9))
MORE = [
    {"obstacles": {"kind": "maze", "corridor": 1, "loops": 0.0}},
    {"obstacles": {"kind": "maze", "corridor": 2, "loops": 1.0}},
    {"obstacles": {"kind": "rooms", "room_size": 4, "door": 1}},
    {"obstacles": {"kind": "rooms", "room_size": 7, "door": 2}},
    {"obstacles": {"kind": "iid", "density": 0.3}},
    {"targets": {"kind": "shifted", "severity": 0.5, "distance": 0.5}},
    {"targets": {"kind": "tempered", "power": 1.0}},
    {"obstacles": {"kind": "rooms", "room_size": 12, "door": 3}, "targets": {"kind": "adversarial", "severity": 1.0}},
    {"obstacles": {"kind": "maze", "corridor": 3}, "prior": {"kind": "misweighted", "severity": 0.5}},
    {"obstacles": {"kind": "primal"}, "targets": {"kind": "tempered", "power": 0.0, "severity": 1.0}},
    {"obstacles": {"kind": "iid", "density": 0.2}, "prior": {"kind": "uninformed", "severity": 0.5}},
]


def scenarios() -> dict[str, Scenario]:
    """Every scenario of the frozen suites and MORE, by label."""
    found = [s for name in ("obstacles", "prior_error", "prior_error_broad") for s in suite_scenarios(
        group_option("suite", name))] + [Scenario.from_dict(values) for values in MORE]  # fmt: skip
    return {s.label: s for s in found}


def digest(scenario: Scenario, seed: int) -> str:
    state = allocate(CONFIG, 3)
    reset_worlds(CONFIG, state, np.ones(3, bool), np.random.default_rng(seed), scenario)
    return _digest(state)


def test_every_suite_scenario_draws_its_recorded_worlds():
    recorded = json.loads(GOLDEN.read_text())
    drawn = {f"{label}_seed{seed}": digest(s, seed) for label, s in scenarios().items() for seed in (0, 1)}
    assert sorted(drawn) == sorted(recorded), "a scenario came or went: record the digests again (module text)"
    moved = sorted(k for k in drawn if drawn[k] != recorded[k])
    assert not moved, f"these worlds are no longer the recorded ones: {moved}"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tempered_at_power_one_is_the_papers_placement(seed):
    paper = Scenario.from_dict({"targets": {"kind": "prior"}})
    assert digest(Scenario.from_dict({"targets": {"kind": "tempered", "power": 1.0}}), seed) == digest(paper, seed)


if __name__ == "__main__":
    GOLDEN.write_text(json.dumps({f"{label}_seed{seed}": digest(s, seed) for label, s in scenarios().items()
                                  for seed in (0, 1)}, indent=1, sort_keys=True) + "\n")  # fmt: skip
    print(f"wrote {GOLDEN}")
