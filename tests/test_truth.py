"""Families of prior error (searchrl/world/truth.py): severity 0 is the paper's placement bit for bit, each family's
law at its largest error, and the prior-quality measure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from searchrl.shared_schema import group_option
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.scenario import Scenario
from searchrl.world.truth import (
    AdversarialTargets,
    OffPriorTargets,
    PriorTargets,
    ShiftedTargets,
    TemperedTargets,
    place_targets,
    prior_quality,
)

CONF = Path(__file__).resolve().parents[1] / "conf" / "scenario"
FAMILIES = [OffPriorTargets, ShiftedTargets, TemperedTargets, AdversarialTargets]


def _bump(n: int = 40, centre: tuple[float, float] = (20.0, 20.0), width: float = 3.0, seed: int = 0):
    """A prior with one narrow Gaussian bump (p), a varied u, and no obstacle."""
    rows, cols = np.mgrid[0:n, 0:n]
    p = np.exp(-((rows - centre[0]) ** 2 + (cols - centre[1]) ** 2) / (2 * width**2)) + 1e-9
    u = np.random.default_rng(seed).random((n, n)) + 0.5
    return p / p.sum(), u / u.sum(), np.ones((n, n), bool)


@pytest.mark.parametrize("family", FAMILIES)
def test_severity_zero_is_the_papers_placement_and_draws_nothing_more(family):
    p, u, free = _bump()
    free[3:6, 3:30] = False  # obstacles too
    paper_rng, rng = np.random.default_rng(7), np.random.default_rng(7)
    want = PriorTargets()(p, u, free, 9, paper_rng)
    np.testing.assert_array_equal(family(severity=0.0)(p, u, free, 9, rng), want)
    assert rng.bit_generator.state == paper_rng.bit_generator.state
    # so the search bound holds there (it assumes the paper's placement), and nowhere above 0
    assert Scenario(targets=family(severity=0.0)).targets_follow_prior
    assert not Scenario(targets=family(severity=0.25)).targets_follow_prior


@pytest.mark.parametrize("family", FAMILIES)
def test_every_family_places_distinct_free_cells(family):
    p, u, free = _bump(n=24)
    free[::3, ::2] = False
    for seed in range(20):
        cells = family(severity=0.7)(p, u, free, 12, np.random.default_rng(seed))
        assert cells.shape == (12, 2) and cells.dtype == np.int64
        assert free[cells[:, 0], cells[:, 1]].all() and len({tuple(c) for c in cells}) == 12


def test_a_shift_moves_the_targets_centroid_by_the_shift():
    """Targets of a bump at (20, 20), shifted by severity 1 × 0.25 × 40 = 10 cells in the drawn direction (the
    placer's first draw): their mean lies where `shift` says, within sampling error."""
    p, u, free = _bump()
    placer = ShiftedTargets(severity=1.0)
    for seed in range(6):
        moved = placer.shift(40, np.random.default_rng(seed))
        assert 9 <= np.hypot(*moved) <= 11  # 10 cells, rounded to whole cells on each axis
        cells = placer(p, u, free, 40, np.random.default_rng(seed))
        np.testing.assert_allclose(cells.mean(axis=0), np.array([20.0, 20.0]) + moved, atol=1.5)
    half = ShiftedTargets(severity=0.5).shift(40, np.random.default_rng(1))
    full = ShiftedTargets(severity=1.0).shift(40, np.random.default_rng(1))
    assert np.allclose(np.array(half) * 2, full, atol=1)  # the same direction, half the distance


def test_sharper_truth_puts_more_targets_on_the_priors_modes_and_flatter_fewer():
    rng = np.random.default_rng(0)
    p = rng.random((30, 30)) ** 4
    p, u, free = p / p.sum(), np.full((30, 30), 1.0) + rng.random((30, 30)), np.ones((30, 30), bool)
    u = u / u.sum()

    def mass(placer) -> float:  # mean prior mass (in units of a uniform cell) at the targets' cells
        cells = np.concatenate([placer(p, u, free, 6, np.random.default_rng(s)) for s in range(200)])
        return float(p[cells[:, 0], cells[:, 1]].mean() * p.size)

    paper, sharper, flatter = mass(PriorTargets()), mass(TemperedTargets(1.0, 4.0)), mass(TemperedTargets(1.0, 0.0))
    assert sharper > 1.3 * paper and flatter < 0.8 * paper and 0.8 < flatter < 1.25  # flatter at 1: about uniform


def test_adversarial_targets_lie_where_the_prior_is_lowest():
    p, u, free = _bump()
    scores = [prior_quality(p, free, AdversarialTargets(1.0)(p, u, free, 8, np.random.default_rng(s)))
              for s in range(50)]  # fmt: skip
    paper = [prior_quality(p, free, place_targets(p, u, free, 8, np.random.default_rng(s))) for s in range(50)]
    assert np.mean(scores) < -0.4 and np.mean(paper) > 0.9


def test_prior_quality_is_zero_for_a_flat_prior_one_at_the_best_cell_and_minus_one_at_the_worst():
    p, _, free = _bump(n=20, centre=(5.0, 14.0))
    flat = np.full((20, 20), 1 / 400)
    targets = np.array([[0, 0], [7, 3], [19, 19]])
    assert prior_quality(flat, free, targets) == 0.0
    assert prior_quality(p, free, np.array([[5, 14]])) == pytest.approx(1.0, abs=1 / 400)
    assert prior_quality(p, free, np.array([np.unravel_index(p.argmin(), p.shape)])) == pytest.approx(-1.0, 1 / 400)
    uniform = [prior_quality(p, free, np.argwhere(free)[np.random.default_rng(s).choice(400, 5, replace=False)])
               for s in range(400)]  # fmt: skip
    assert abs(np.mean(uniform)) < 0.05  # targets that ignore the prior score 0 on average
    free[5, 14] = False  # only free cells are ranked
    assert prior_quality(p, free, np.array([[5, 13]])) > prior_quality(p, np.ones_like(free), np.array([[5, 13]]))
    assert np.isnan(prior_quality(p, free, np.zeros((0, 2), np.int64)))


@pytest.mark.parametrize("name, kind", [("shifted", "shifted"), ("sharper", "tempered"), ("flatter", "tempered"),
                                        ("adversarial", "adversarial"), ("off_prior", "off_prior")])  # fmt: skip
def test_each_family_has_a_scenario_file_with_a_label_of_its_own(name, kind):
    scenario = Scenario.from_dict(group_option("scenario", name))
    assert scenario.targets.kind == kind and not scenario.targets_follow_prior
    scenario.check(WorldConfig())
    labels = {Scenario.from_dict(group_option("scenario", path.stem)).label for path in CONF.glob("*.yaml")}
    assert len(labels) == len(list(CONF.glob("*.yaml")))  # no two scenario files share a label


@pytest.mark.parametrize("targets, message", [
    ({"kind": "shifted", "severity": -0.1}, "scenario.targets.severity=-0.1 is not allowed: 0 <= severity <= 1"),
    ({"kind": "shifted", "distance": 0.0}, "scenario.targets.distance=0.0 is not allowed: 0 < distance <= 1"),
    ({"kind": "tempered", "power": 20}, "scenario.targets.power=20 is not allowed: 0 <= power <= 16"),
    ({"kind": "adversarial", "severity": float("nan")}, "scenario.targets.severity=nan is not allowed"),
    ({"kind": "adversarial", "power": 2}, "scenario.targets.power=2 is not allowed: targets of kind adversarial take"),
])  # fmt: skip
def test_bad_family_settings_are_named(targets, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Scenario.from_dict({"targets": targets}).check(WorldConfig())


@pytest.mark.parametrize("severity, power", [(0.0, 4.0), (0.5, 4.0), (1.0, 4.0), (1.0, 2.0), (0.5, 0.0)])
def test_tempered_truth_follows_p_to_the_power_its_severity_sets(severity, power):
    """a = 1 + severity·(power − 1): severity 0 is the paper's placement itself, draw for draw, and 0.5 with power 4
    places from p^2.5, the same draws as placing from that map directly."""
    from searchrl.world.truth import TemperedTargets, place_targets

    rng = np.random.default_rng(0)
    p = rng.random((12, 12)) ** 3
    p /= p.sum()
    u = rng.random((12, 12))
    u /= u.sum()
    free = np.ones((12, 12), bool)
    got = TemperedTargets(severity=severity, power=power).wrong(p, u, free, 6, np.random.default_rng(5))
    tempered = p ** (1.0 + severity * (power - 1.0))
    want = place_targets(tempered / tempered.sum(), u, free, 6, np.random.default_rng(5))
    np.testing.assert_array_equal(got, want)


def test_adversarial_ties_take_the_mirrored_masses_in_cell_order(monkeypatch):
    """Cells of equal p are ranked in row-major order (a stable sort): of two tied cells the earlier takes the larger
    mirrored mass, so the upside-down map does not depend on how a sort orders ties."""
    drawn_from = []

    def remember_weights(severity, weights, p, u, free, count, rng):
        drawn_from.append(weights)
        return np.zeros((0, 2), np.int64)

    monkeypatch.setattr("searchrl.world.truth._replace_share", remember_weights)
    p = np.random.default_rng(0).integers(1, 4, (40, 40)).astype(float)  # three values: 1,600 cells, many ties
    p /= p.sum()
    AdversarialTargets(1.0).wrong(p, p, np.ones((40, 40), bool), 4, np.random.default_rng(0))
    values = p.ravel().tolist()
    ranked = sorted(range(len(values)), key=lambda cell: (values[cell], cell))  # lowest first, ties by cell
    want = np.empty(len(values))
    want[ranked] = sorted(values, reverse=True)
    np.testing.assert_array_equal(drawn_from[0].ravel(), want)


def test_weights_that_leave_no_mass_on_the_free_cells_left_place_uniformly():
    """A replaced target is drawn from the weights over the free cells left, or uniformly where they hold no mass
    there (as without weights): the same draws as `OffPriorTargets`' uniform placement."""
    from searchrl.world.truth import _replace_share

    p, u, free = _bump(n=12)
    no_mass = np.zeros((12, 12))
    got = _replace_share(1.0, no_mass, p, u, free, 5, np.random.default_rng(3))
    np.testing.assert_array_equal(got, _replace_share(1.0, None, p, u, free, 5, np.random.default_rng(3)))


def test_no_target_is_no_cell_and_a_map_without_room_for_them_is_named():
    p, u, free = _bump(n=12)
    none = place_targets(p, u, free, 0, np.random.default_rng(0))
    assert none.shape == (0, 2) and none.dtype == np.int64
    two_cells = np.zeros((12, 12), bool)
    two_cells[3, 4] = two_cells[7, 1] = True  # three targets cannot take distinct cells of two
    with pytest.raises(RuntimeError, match=r"^could not place 3 targets in 1000 batches \(maps too peaked\?\)$"):
        place_targets(p, u, two_cells, 3, np.random.default_rng(0))
