"""Every scenario part's check at its boundaries: the last value allowed passes, the first beyond is refused with
its whole one-line message (the name, the value, what is allowed), so a bound moved by one or a message garbled
fails here. The exact room checks are hit at equality: the largest team that fits passes, one more is refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.obstacles import IidObstacles, MazeObstacles, PrimalObstacles, RoomObstacles
from searchrl.world.prior import MisweightedPrior, MixturePrior, UninformedPrior
from searchrl.world.scenario import Scenario, ScenarioMix, scenario_grid
from searchrl.world.truth import AdversarialTargets, OffPriorTargets, ShiftedTargets, TemperedTargets

W = WorldConfig()  # n in [20, 128], 8 agents, up to 16 targets: 24 distinct start cells
SMALL = WorldConfig(world_size=(8, 8), n_agents=17, n_targets=(8, 8))  # 25 start cells in 64
CROWD = WorldConfig(world_size=(20, 20), n_agents=281, n_targets=(16, 16))  # 297 start cells in 400

ALLOWED = [
    (IidObstacles(density=0.0), W),
    (IidObstacles(density=0.94), W),  # int(400 · 0.06) = 24 free cells: room for 24
    (IidObstacles(density=0.5, connected=True), W),
    (PrimalObstacles(), SMALL),  # int(64 · 0.4) = 25
    (MazeObstacles(corridor=1, loops=0.0), W),
    (MazeObstacles(corridor=16, loops=1.0), WorldConfig(world_size=(40, 40))),
    (MazeObstacles(corridor=9), W),  # two lattice cells a side at n = 20
    (MazeObstacles(corridor=3), CROWD),  # 5² squares of 9 cells and 24 openings of 3: 297 free
    (RoomObstacles(room_size=4, door=1), W),
    (RoomObstacles(room_size=20, door=19), W),
    (RoomObstacles(room_size=1024, door=1023), WorldConfig(world_size=(1024, 1024))),
    (RoomObstacles(room_size=4, door=1), WorldConfig(world_size=(10, 10), n_agents=64, n_targets=(16, 16))),  # 80
    (OffPriorTargets(severity=0.0), W),
    (OffPriorTargets(severity=1.0), W),
    (ShiftedTargets(severity=1), W),  # an integer, as YAML reads `severity: 1`
    (AdversarialTargets(severity=1.0), W),
    (ShiftedTargets(distance=1.0), W),
    (TemperedTargets(power=0.0), W),
    (TemperedTargets(power=16.0), W),
    (MixturePrior(variance_scale=0.0500001), W),  # just above variance_floor / smallest n = 1 / 20
    (MixturePrior(variance_scale=1e6), W),
    (MisweightedPrior(severity=1.0), W),
    (UninformedPrior(severity=0.0), W),
]

ROOM = "agents and targets start on distinct cells: n_agents + max targets ="
REFUSED = [
    (IidObstacles(density=-0.0001), W, "scenario.obstacles.density=-0.0001 is not allowed: 0 <= density < 1"),
    (IidObstacles(density=1.0), W, "scenario.obstacles.density=1.0 is not allowed: 0 <= density < 1"),
    (IidObstacles(density=float("nan")), W, "scenario.obstacles.density=nan is not allowed: 0 <= density < 1"),
    (IidObstacles(density=0.1, connected=1), W, "scenario.obstacles.connected=1 is not allowed: true or false"),
    (IidObstacles(density=0.9425), W, f"scenario.obstacles.density=0.9425 is not allowed: {ROOM} 24 must fit the "
     "about 23 free cells of the smallest world (n=20)"),
    (PrimalObstacles(), WorldConfig(world_size=(8, 8), n_agents=18, n_targets=(8, 8)),
     f"scenario.obstacles.kind='primal' is not allowed: {ROOM} 26 must fit the about 25 free cells of the smallest "
     "world (n=8)"),
    (MazeObstacles(corridor=0), W, "scenario.obstacles.corridor=0 is not allowed: an integer 1 <= corridor <= 16 "
     "(cells)"),
    (MazeObstacles(corridor=17), WorldConfig(world_size=(40, 40)), "scenario.obstacles.corridor=17 is not allowed: an "
     "integer 1 <= corridor <= 16 (cells)"),
    (MazeObstacles(corridor=2.0), W, "scenario.obstacles.corridor=2.0 is not allowed: an integer 1 <= corridor <= 16 "
     "(cells)"),
    (MazeObstacles(loops=-0.01), W, "scenario.obstacles.loops=-0.01 is not allowed: 0 <= loops <= 1"),
    (MazeObstacles(loops=1.01), W, "scenario.obstacles.loops=1.01 is not allowed: 0 <= loops <= 1"),
    (MazeObstacles(corridor=10), W, "scenario.obstacles.corridor=10 is not allowed: at most 9 in the smallest world "
     "(n=20): two corridors and a wall a side, else the maze is one open room"),
    (MazeObstacles(corridor=3), WorldConfig(world_size=(20, 20), n_agents=282, n_targets=(16, 16)),
     f"scenario.obstacles.corridor=3 is not allowed: {ROOM} 298 must fit the about 297 free cells of the smallest "
     "world (n=20)"),
    (RoomObstacles(room_size=3, door=1), W, "scenario.obstacles.room_size=3 is not allowed: an integer 4 <= room_size "
     "<= 1024 (cells)"),
    (RoomObstacles(room_size=1025), WorldConfig(world_size=(1024, 1024)), "scenario.obstacles.room_size=1025 is not "
     "allowed: an integer 4 <= room_size <= 1024 (cells)"),
    (RoomObstacles(room_size=12.0), W, "scenario.obstacles.room_size=12.0 is not allowed: an integer 4 <= room_size "
     "<= 1024 (cells)"),
    (RoomObstacles(door=0), W, "scenario.obstacles.door=0 is not allowed: an integer 1 <= door < room_size (cells)"),
    (RoomObstacles(room_size=12, door=12), W, "scenario.obstacles.door=12 is not allowed: an integer 1 <= door < "
     "room_size (cells)"),
    (RoomObstacles(room_size=21), W, "scenario.obstacles.room_size=21 is not allowed: at most the smallest world's "
     "side n=20: a larger room is never divided, and the world is one open room"),
    (RoomObstacles(room_size=4, door=1), WorldConfig(world_size=(10, 10), n_agents=65, n_targets=(16, 16)),
     f"scenario.obstacles.room_size=4 is not allowed: {ROOM} 81 must fit the about 80 free cells of the smallest "
     "world (n=10)"),
    (OffPriorTargets(severity=1.01), W, "scenario.targets.severity=1.01 is not allowed: 0 <= severity <= 1 (0: the "
     "paper's placement; 1: the family's most wrong prior)"),
    (AdversarialTargets(severity=-0.01), W, "scenario.targets.severity=-0.01 is not allowed: 0 <= severity <= 1 (0: "
     "the paper's placement; 1: the family's most wrong prior)"),
    (ShiftedTargets(distance=0.0), W, "scenario.targets.distance=0.0 is not allowed: 0 < distance <= 1 (the largest "
     "shift, as a fraction of the world's side)"),
    (ShiftedTargets(distance=1.01), W, "scenario.targets.distance=1.01 is not allowed: 0 < distance <= 1 (the "
     "largest shift, as a fraction of the world's side)"),
    (ShiftedTargets(severity=2.0), W, "scenario.targets.severity=2.0 is not allowed: 0 <= severity <= 1 (0: the "
     "paper's placement; 1: the family's most wrong prior)"),
    (TemperedTargets(power=-0.01), W, "scenario.targets.power=-0.01 is not allowed: 0 <= power <= 16 (> 1: the truth "
     "sharper than the prior; < 1: flatter)"),
    (TemperedTargets(power=16.01), W, "scenario.targets.power=16.01 is not allowed: 0 <= power <= 16 (> 1: the truth "
     "sharper than the prior; < 1: flatter)"),
    (TemperedTargets(severity=-1.0), W, "scenario.targets.severity=-1.0 is not allowed: 0 <= severity <= 1 (0: the "
     "paper's placement; 1: the family's most wrong prior)"),
    (MixturePrior(variance_scale=0.0), W, "scenario.prior.variance_scale=0.0 is not allowed: null (the world's "
     "prob_variance_scale) or 0 < scale <= 1e6"),
    (MixturePrior(variance_scale=1e6 + 0.5), W, "scenario.prior.variance_scale=1000000.5 is not allowed: null (the "
     "world's prob_variance_scale) or 0 < scale <= 1e6"),
    (ShiftedTargets(severity="high"), W, "scenario.targets.severity='high' is not allowed: 0 <= severity <= 1 (0: the "
     "paper's placement; 1: the family's most wrong prior)"),
    (MixturePrior(variance_scale=1.01e6), W, "scenario.prior.variance_scale=1010000.0 is not allowed: null (the "
     "world's prob_variance_scale) or 0 < scale <= 1e6"),
    (MixturePrior(variance_scale=0.05), W, "scenario.prior.variance_scale=0.05 is not allowed: scale · smallest n must "
     "exceed variance_floor=1.0"),
    (MisweightedPrior(severity=1.01), W, "scenario.prior.severity=1.01 is not allowed: 0 <= severity <= 1 (0: the "
     "paper's prior; 1: the family's most wrong)"),
    (UninformedPrior(severity=-0.01), W, "scenario.prior.severity=-0.01 is not allowed: 0 <= severity <= 1 (0: the "
     "paper's prior; 1: the family's most wrong)"),
    (UninformedPrior(variance_scale=0.05), W, "scenario.prior.variance_scale=0.05 is not allowed: scale · smallest n "
     "must exceed variance_floor=1.0"),
    (UninformedPrior(variance_scale=0.0), W, "scenario.prior.variance_scale=0.0 is not allowed: null (the world's "
     "prob_variance_scale) or 0 < scale <= 1e6"),
]  # fmt: skip


@pytest.mark.parametrize(("part", "config"), ALLOWED, ids=[repr(p) for p, _ in ALLOWED])
def test_the_last_value_allowed_passes(part, config):
    part.check(config)


@pytest.mark.parametrize(("part", "config", "message"), REFUSED, ids=[m.split(" is")[0] for *_, m in REFUSED])
def test_the_first_value_beyond_is_refused_in_one_whole_line(part, config, message):
    with pytest.raises(ConfigError) as refused:
        part.check(config)
    assert str(refused.value) == message


SHIFTED = {"targets": {"kind": "shifted"}}
GRID_REFUSED = [
    ({"families": {"shifted": SHIFTED}, "severities": [], "variance_scales": [None]},
     "suite.severities=[] is not allowed: severities in (0, 1] (severity 0, the prior right, comes once per "
     "sharpness)"),
    ({"families": {}, "severities": [0.0], "variance_scales": [None]},
     "suite.severities=[0.0] is not allowed: severities in (0, 1] (severity 0, the prior right, comes once per "
     "sharpness)"),
    ({"families": {}, "severities": [0.5, 1.5], "variance_scales": [None]},
     "suite.severities=[0.5, 1.5] is not allowed: severities in (0, 1] (severity 0, the prior right, comes once per "
     "sharpness)"),
    ({"families": {}, "severities": [], "variance_scales": []},
     "suite.variance_scales=[] is not allowed: one or more (null: the world's)"),
    ({"families": {"bare": {}}, "severities": [1.0], "variance_scales": [None]},
     "suite.families.bare={} is not allowed: the parts the family sets: prior and/or targets, with a kind"),
    ({"families": {"walls": {"obstacles": {"kind": "maze"}}}, "severities": [1.0], "variance_scales": [None]},
     "suite.families.walls={'obstacles': {'kind': 'maze'}} is not allowed: the parts the family sets: prior and/or "
     "targets, with a kind"),
    ({"families": {"named": "shifted"}, "severities": [1.0], "variance_scales": [None]},
     "suite.families.named='shifted' is not allowed: the parts the family sets: prior and/or targets, with a kind"),
]  # fmt: skip


@pytest.mark.parametrize(("args", "message"), GRID_REFUSED, ids=[m.split(" is")[0] for _, m in GRID_REFUSED])
def test_a_suites_grid_is_refused_under_its_key(args, message):
    with pytest.raises(ConfigError) as refused:
        scenario_grid(**args)
    assert str(refused.value) == message
    with pytest.raises(ConfigError) as refused:  # a mix's own key, the same words
        scenario_grid(**args, name="scenario.mix")
    assert str(refused.value) == message.replace("suite.", "scenario.mix.", 1)


def test_a_grid_takes_one_small_severity_families_of_both_parts_and_obstacles_under_every_scenario():
    both = {"prior": {"kind": "uninformed"}, "targets": {"kind": "shifted"}}
    grid = scenario_grid({"both": both}, [1e-9], [1.0, None], obstacles={"kind": "maze", "corridor": 3})
    assert len(grid) == 2 * (1 + 1)  # per sharpness: the prior right, the family at its one severity
    assert all(isinstance(s.obstacles, MazeObstacles) and s.obstacles.corridor == 3 for s in grid)
    assert [s.prior.variance_scale for s in grid] == [1.0, 1.0, None, None]
    assert isinstance(grid[1].prior, UninformedPrior) and isinstance(grid[1].targets, ShiftedTargets)
    assert grid[1].prior.severity == grid[1].targets.severity == 1e-9
    assert scenario_grid({}, [], [None]) == [Scenario()]  # no family needs no severity: the paper's scenario alone


def test_a_mix_names_its_first_unknown_key_carries_obstacles_and_gives_its_spec_back():
    with pytest.raises(ConfigError) as refused:
        ScenarioMix.from_spec({"zeta": 1, "familes": {}})
    assert str(refused.value) == ("scenario.mix.familes is not allowed: a mix has families, severities, "
                                  "variance_scales, obstacles and scenarios")  # fmt: skip
    spec = {"obstacles": {"kind": "rooms", "room_size": 12, "door": 3}, "families": {"shifted": SHIFTED},
            "severities": [1.0]}  # fmt: skip
    mix = ScenarioMix.from_spec(spec)
    assert all(isinstance(s.obstacles, RoomObstacles) for s in mix.scenarios) and len(mix.scenarios) == 2
    assert mix.to_dict() == {"mix": spec} and Scenario.from_dict(mix.to_dict()) == mix
    mix.check(W)
    with pytest.raises(ConfigError, match=r"^scenario\.obstacles\.room_size=12 is not allowed: at most"):
        mix.check(WorldConfig(world_size=(10, 20)))  # every member checked, here against n = 10
    with pytest.raises(ConfigError) as refused:
        ScenarioMix.from_spec({"families": {"shifted": SHIFTED}, "severities": [2.0]})
    assert str(refused.value).startswith("scenario.mix.severities=[2.0] is not allowed")


def test_a_scenario_names_its_label_family_and_severity_from_its_parts():
    """The label joins the parts' labels (obstacles, prior, targets) with "+", "paper" when none has one; the
    family joins the families drawn above severity 0; the severity is the largest."""
    assert Scenario().label == "paper" and Scenario().family == "paper" and Scenario().severity == 0.0
    both = Scenario(obstacles=IidObstacles(density=0.2), prior=UninformedPrior(severity=0.25),
                    targets=ShiftedTargets(severity=0.5))  # fmt: skip
    parts = [IidObstacles(density=0.2).label, UninformedPrior(severity=0.25).label, ShiftedTargets(severity=0.5).label]
    assert all(parts) and both.label == "+".join(parts)
    assert both.family == "uninformed+shifted" and both.severity == 0.5
    assert Scenario(prior=UninformedPrior(severity=0.0), targets=ShiftedTargets(severity=0.5)).family == "shifted"
    assert Scenario(targets=ShiftedTargets(severity=0.0)).family == "paper"
    assert Scenario.from_dict(both.to_dict()) == both and both.pick(None) is both  # a scenario draws nothing
    assert Scenario.from_dict(None) == Scenario.from_dict({}) == Scenario.from_dict({"mix": None}) == Scenario()
    with pytest.raises(ConfigError) as refused:
        Scenario.from_dict({"walls": {}, "zones": {}})
    assert str(refused.value) == ("scenario.walls is not allowed: a scenario has obstacles, prior and targets "
                                  "(or a mix)")  # fmt: skip
    with pytest.raises(ConfigError) as refused:
        Scenario.from_dict({"targets": {"kind": "prior", "spread": 2}})
    assert str(refused.value) == "scenario.targets.spread=2 is not allowed: targets of kind prior take no settings"


def test_a_mix_is_named_by_its_members_picks_one_per_draw_and_follows_the_prior_only_if_all_do():
    right = ScenarioMix.from_spec({"families": {}, "severities": [], "obstacles": {"kind": "maze", "corridor": 3}})
    wrong = ScenarioMix.from_spec({"families": {"shifted": SHIFTED}, "severities": [0.5, 1.0]})
    assert right.family == wrong.family == "mix" and math.isnan(wrong.severity)
    assert right.label.startswith("mix-") and len(right.label) == len("mix-") + 8 and right.label != wrong.label
    assert ScenarioMix.from_spec({"families": {"shifted": SHIFTED}, "severities": [0.5, 1.0]}).label == wrong.label
    assert right.targets_follow_prior and not wrong.targets_follow_prior
    # the right prior once per severity, then the family at each: picked uniformly by one integer per reset
    assert [s.severity for s in wrong.scenarios] == [0.0, 0.0, 0.5, 1.0]
    rng, again = np.random.default_rng(3), np.random.default_rng(3)
    assert [wrong.pick(rng) for _ in range(20)] == [wrong.scenarios[int(again.integers(4))] for _ in range(20)]
    explicit = ScenarioMix.from_spec({"severities": [0.5, 1.0], "scenarios": [{"obstacles": {"kind": "primal"}}]})
    assert [type(s.obstacles).__name__ for s in explicit.scenarios].count("PrimalObstacles") == 2  # weighed as one
    assert Scenario.from_dict({"mix": {"families": {}}, "targets": None, "prior": None}) == ScenarioMix.from_spec(
        {"families": {}}
    )
    with pytest.raises(ConfigError) as refused:
        Scenario.from_dict({"mix": {"families": {}}, "targets": {"kind": "prior"}})
    assert str(refused.value) == ("scenario.targets is not allowed with scenario.mix: a mix draws whole scenarios "
                                  "(set the part in its families, or null it)")  # fmt: skip


def test_a_registered_part_kind_is_read_by_name_and_a_taken_or_unknown_one_is_refused():
    from dataclasses import dataclass

    from searchrl.world import scenario

    @dataclass(frozen=True)
    class _Again(IidObstacles):
        kind = "iid"

    with pytest.raises(ConfigError) as refused:
        scenario.register_part("obstacles", _Again)
    assert str(refused.value) == ("scenario.obstacles.kind='iid' cannot be registered: a new name is needed, not one "
                                  f"of {', '.join(scenario.PARTS['obstacles'])}")  # fmt: skip

    class _Nameless:  # no `kind`: refused the same way, not an AttributeError
        pass

    with pytest.raises(ConfigError, match=r"^scenario\.prior\.kind=None cannot be registered"):
        scenario.register_part("prior", _Nameless)
    with pytest.raises(ConfigError, match=r"^part=.walls. is not allowed: one of obstacles, prior, targets$"):
        scenario.register_part("walls", _Again)

    @dataclass(frozen=True)
    class _Dense(IidObstacles):
        kind = "dense_test"

    try:
        scenario.register_part("obstacles", _Dense)
        assert Scenario.from_dict({"obstacles": {"kind": "dense_test", "density": 0.3}}).obstacles == _Dense(0.3)
    finally:
        scenario.PARTS["obstacles"].pop("dense_test", None)
