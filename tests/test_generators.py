"""Scenario generators (searchrl/world/scenario.py): the paper's draws kept bit for bit, the laws of the other
scenarios, their checks and their mapping form, and one override to choose them."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.reset import reset_worlds
from searchrl.world.scenario import PAPER, IidObstacles, Scenario
from searchrl.world.state import allocate
from searchrl.world.truth import OffPriorTargets, PriorTargets, place_targets

GOLDEN = Path(__file__).resolve().parent / "golden" / "worlds.json"


def _digest(state) -> str:
    digest = hashlib.sha256()
    for name in ("size", "p", "u", "blocked", "belief", "pos", "target_pos", "target_valid", "n_targets", "obs_scale"):
        digest.update(np.ascontiguousarray(getattr(state, name)).tobytes())
    return digest.hexdigest()[:16]


def test_the_paper_scenario_and_iid_obstacles_draw_the_worlds_recorded_before_scenarios_existed():
    """tests/golden/worlds.json holds digests of worlds reset at 05d7673, when the world drew obstacles from
    WorldConfig.obstacle_density: the same seeds give the same maps, obstacles, targets and agents."""
    recorded = json.loads(GOLDEN.read_text())
    config = WorldConfig(world_size=(12, 40), n_agents=6, n_targets=(2, 9), n_distributions=(3, 9))
    for density in (0.0, 0.1, 0.3):
        for seed in (0, 1, 2):
            state = allocate(config, 3)
            scenario = PAPER if density == 0 else Scenario(IidObstacles(density))
            reset_worlds(config, state, np.ones(3, bool), np.random.default_rng(seed), scenario)
            assert _digest(state) == recorded[f"density{density}_seed{seed}"], (density, seed)


def _prior(n: int = 20, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    p = rng.random((n, n)) ** 8  # peaked, so the prior's placement is far from uniform
    u = rng.random((n, n))
    return p / p.sum(), u / u.sum(), np.ones((n, n), bool)


def test_off_prior_at_severity_zero_draws_exactly_the_papers_placement():
    p, u, free = _prior()
    paper_rng, rng = np.random.default_rng(3), np.random.default_rng(3)
    want = PriorTargets()(p, u, free, 12, paper_rng)
    np.testing.assert_array_equal(OffPriorTargets(0.0)(p, u, free, 12, rng), want)
    assert rng.bit_generator.state == paper_rng.bit_generator.state  # nothing more drawn: later draws agree too


def test_off_prior_at_severity_one_places_every_target_uniformly_on_free_cells():
    """The count of targets per cell over many worlds fits the uniform law over free cells (chi-square), and the
    prior's peaks draw no more than their share; obstacles never hold one."""
    p, u, free = _prior(10)
    free[0, :] = False
    counts = np.zeros((10, 10))
    rng = np.random.default_rng(0)
    for _ in range(2000):
        cells = OffPriorTargets(1.0)(p, u, free, 5, rng)
        assert len({tuple(c) for c in cells.tolist()}) == 5 and free[cells[:, 0], cells[:, 1]].all()
        np.add.at(counts, (cells[:, 0], cells[:, 1]), 1)
    observed = counts[free]
    assert stats.chisquare(observed).pvalue > 1e-3
    prior_counts = np.zeros((10, 10))
    for _ in range(300):
        cells = place_targets(p, u, free, 5, rng)
        np.add.at(prior_counts, (cells[:, 0], cells[:, 1]), 1)
    assert stats.chisquare(prior_counts[free]).pvalue < 1e-6  # the prior's own placement is far from uniform


def test_off_prior_places_a_share_of_the_targets_uniformly():
    """At severity 0.5 about half of the targets land where the prior puts almost nothing."""
    n = 30
    p = np.full((n, n), 1e-9)
    p[:5, :5] = 1.0  # the prior puts everything in one corner
    u = np.random.default_rng(0).random((n, n))
    p, u, free = p / p.sum(), u / u.sum(), np.ones((n, n), bool)
    rng = np.random.default_rng(1)
    outside = [(~((c[:, 0] < 5) & (c[:, 1] < 5))).mean() for c in
               (OffPriorTargets(0.5)(p, u, free, 8, rng) for _ in range(400))]  # fmt: skip
    share_uniform_outside = 1 - 25 / n**2
    assert abs(np.mean(outside) - 0.5 * share_uniform_outside) < 0.03


def test_targets_off_the_prior_are_what_the_world_places_while_the_agents_keep_the_prior():
    """From one seed a world draws the same prior under both scenarios (the targets are drawn after it)."""
    config = WorldConfig(world_size=(30, 30), n_agents=4, n_targets=(6, 6))
    for seed in range(3):
        paper = SearchWorld(config, 1, seed=seed)
        off = SearchWorld(config, 1, seed=seed, scenario=Scenario(targets=OffPriorTargets()))
        paper.reset(), off.reset()
        np.testing.assert_array_equal(off.state.p, paper.state.p)
        np.testing.assert_array_equal(off.state.belief, paper.state.belief)
        assert not np.array_equal(off.state.target_pos, paper.state.target_pos)


def test_a_scenario_reads_and_writes_its_mapping_and_names_each_bad_value():
    walls = Scenario(IidObstacles(0.2), OffPriorTargets(0.5))
    assert Scenario.from_dict(walls.to_dict()) == walls
    assert Scenario.from_dict(None) == Scenario.from_dict({}) == PAPER
    assert (PAPER.label, walls.label, Scenario(targets=OffPriorTargets(1.0)).label) == (
        "paper",
        "iid0.2+off_prior0.5",
        "off_prior1",
    )
    assert Scenario(IidObstacles(0.0), PriorTargets()).label == "paper" and PAPER.targets_follow_prior
    bad = [
        ({"walls": {}}, "scenario.walls is not allowed"),
        (
            {"obstacles": {"kind": "caves"}},
            "scenario.obstacles.kind='caves' is not allowed: one of iid, primal, maze, rooms",
        ),
        ({"targets": {"kind": "prior", "severity": 1}}, "scenario.targets.severity=1 is not allowed"),
        ({"targets": {"kind": "off_prior", "density": 1}}, "scenario.targets.density=1 is not allowed"),
    ]
    for values, message in bad:
        with pytest.raises(ConfigError, match=message.replace("(", r"\(")):
            Scenario.from_dict(values)


@pytest.mark.parametrize("scenario, message", [
    (Scenario(IidObstacles(1.0)), "scenario.obstacles.density=1.0 is not allowed: 0 <= density < 1"),
    (Scenario(IidObstacles(float("nan"))), "scenario.obstacles.density=nan"),
    (Scenario(targets=OffPriorTargets(1.5)), "scenario.targets.severity=1.5 is not allowed"),
])  # fmt: skip
def test_a_scenario_checks_its_values_against_the_world(scenario, message):
    with pytest.raises(ConfigError, match=message):
        scenario.check(WorldConfig())
    with pytest.raises(ConfigError, match=message):
        SearchWorld(WorldConfig(), 1, scenario=scenario)


def test_obstacle_density_counts_against_room_for_agents_and_targets():
    # 5×5 at 50 % obstacles leaves int(12.5) = 12 free cells: 10 agents + 3 targets do not fit.
    with pytest.raises(ConfigError, match=r"^scenario.obstacles.density=0.5 .* = 13 must fit the about 12 free cells"):
        IidObstacles(0.5).check(WorldConfig(world_size=(5, 5), n_agents=10, n_targets=(1, 3)))
    IidObstacles(0.5).check(WorldConfig(world_size=(5, 5), n_agents=10, n_targets=(1, 2)))
