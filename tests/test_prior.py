"""The prior part of a scenario (searchrl/world/prior.py): the paper's draw bit for bit, sharper priors, mis-weighted
modes and agents that know less, each family's law, and what the search bound may assume."""

from __future__ import annotations

import numpy as np
import pytest

from searchrl.shared_schema import group_option
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.prior import MisweightedPrior, MixturePrior, UninformedPrior
from searchrl.world.reset import reset_world
from searchrl.world.scenario import PAPER, Scenario
from searchrl.world.state import allocate
from searchrl.world.truth import prior_qualities

CONFIG = WorldConfig(world_size=(30, 30), n_targets=(6, 6), n_distributions=(4, 4), n_agents=3)


def _draw(scenario: Scenario, seed: int, config: WorldConfig = CONFIG):
    state = allocate(config, 1)
    rng = np.random.default_rng(seed)
    reset_world(config, state, 0, rng, scenario)
    return state, rng


def _inner(state, array):
    h, n = state.halo, int(state.size[0])
    return array[0, h : h + n, h : h + n]


@pytest.mark.parametrize("family", [MisweightedPrior, UninformedPrior])
@pytest.mark.parametrize("obstacles", [0.0, 0.2])
def test_severity_zero_draws_the_papers_world_and_nothing_more(family, obstacles):
    base = Scenario.from_dict({"obstacles": {"kind": "iid", "density": obstacles}})
    for seed in range(5):
        want, want_rng = _draw(base, seed)
        got, rng = _draw(Scenario(base.obstacles, base.targets, family(severity=0.0)), seed)
        for name in ("p", "u", "belief", "target_pos", "pos", "blocked"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
        assert rng.bit_generator.state == want_rng.bit_generator.state
    assert Scenario(prior=family(severity=0.0)).targets_follow_prior
    assert not Scenario(prior=family(severity=0.5)).targets_follow_prior


def test_the_default_prior_is_the_papers_and_a_variance_scale_sharpens_it():
    for seed in range(3):
        want, _ = _draw(PAPER, seed)
        got, _ = _draw(Scenario(prior=MixturePrior(variance_scale=CONFIG.prob_variance_scale)), seed)
        np.testing.assert_array_equal(got.p, want.p)

    # Sharper Gaussians (σ² < 1·n) put the prior's mass on fewer cells and the targets where it says
    def peak(scale):
        return np.mean([_inner(s, s.p).max() for s in (_draw(Scenario(prior=MixturePrior(scale)), seed)[0]
                                                        for seed in range(30))])  # fmt: skip

    peak = {scale: peak(scale) for scale in (None, 1.0)}
    assert peak[1.0] > 2 * peak[None]
    quality = {scale: np.mean([prior_qualities(_draw(Scenario(prior=MixturePrior(scale)), seed)[0])[0]
                               for seed in range(60)]) for scale in (None, 1.0)}  # fmt: skip
    assert quality[1.0] > quality[None] + 0.1
    assert Scenario(prior=MixturePrior(1.0)).targets_follow_prior and Scenario(prior=MixturePrior(1.0)).label == "var1"


def test_uninformed_agents_hold_a_flat_prior_while_the_targets_stay_where_the_paper_puts_them():
    for seed in range(5):
        want, _ = _draw(PAPER, seed)
        got, _ = _draw(Scenario(prior=UninformedPrior(severity=1.0)), seed)
        np.testing.assert_array_equal(got.target_pos, want.target_pos)  # the truth is the paper's, drawn the same
        np.testing.assert_array_equal(got.pos, want.pos)
        p = _inner(got, got.p)
        assert np.allclose(p, 1.0 / p.size)
        np.testing.assert_array_equal(got.u, want.u)  # u cannot say "no information" (prior.py); it stays
        assert np.allclose(got.belief[0, :, 0], got.p[0])  # the agents start from it
        assert prior_qualities(got)[0] == 0.0  # a flat prior ranks every cell alike: no better than uniform
        assert prior_qualities(got).dtype == np.float64
    half, _ = _draw(Scenario(prior=UninformedPrior(severity=0.5)), 0)
    full, _ = _draw(PAPER, 0)
    np.testing.assert_allclose(_inner(half, half.p), 0.5 * _inner(full, full.p) + 0.5 / 900, rtol=1e-6)


def test_misweighted_truth_is_the_priors_gaussians_reweighted():
    config = WorldConfig(world_size=(40, 40), n_targets=(8, 8), n_distributions=(6, 6), n_agents=2)
    distance = {}
    for severity in (0.0, 0.5, 1.0):
        prior = MisweightedPrior(severity=severity)
        gaps = []
        for seed in range(20):
            draw = prior(config, 40, 6, np.random.default_rng(seed))
            assert np.isclose(draw.truth_p.sum(), 1.0) and draw.truth_p.min() >= config.eta / 1600 * (1 - 1e-9)
            np.testing.assert_array_equal(draw.p, MixturePrior()(config, 40, 6, np.random.default_rng(seed)).p)
            gaps.append(np.abs(draw.truth_p - draw.p).sum())
        distance[severity] = np.mean(gaps)
    assert distance[0.0] == 0.0 < distance[0.5] < distance[1.0]
    # the weights' law: the truth's mass over the Gaussians' centres is a Dirichlet reweighting, not noise: the
    # truth is a combination of the m densities with weights (1 - s) + s·m·d, d on the simplex
    from searchrl.world.maps import gaussian_components

    rng = np.random.default_rng(3)
    densities = gaussian_components(40, 6, config.prob_variance_scale * 40, config.variance_floor, config.rho_max, rng)
    truth = MisweightedPrior(severity=1.0)(config, 40, 6, np.random.default_rng(3)).truth_p
    mixture = (truth - config.eta / 1600) / (1 - config.eta)  # eq. 7 undone: Σ w_i G_i / Σ w_i G_i's total
    weights, *_ = np.linalg.lstsq(densities.reshape(6, -1).T, mixture.ravel(), rcond=None)
    weights = weights / weights.sum() * 6
    assert np.all(weights > -1e-6) and np.isclose(weights.sum(), 6) and weights.std() > 0.1


def test_bad_prior_settings_are_named():
    with pytest.raises(ConfigError, match=r"scenario\.prior\.severity"):
        Scenario(prior=MisweightedPrior(severity=1.5)).check(CONFIG)
    with pytest.raises(ConfigError, match=r"scenario\.prior\.variance_scale"):
        Scenario(prior=MixturePrior(variance_scale=-1.0)).check(CONFIG)
    with pytest.raises(ConfigError, match=r"scenario\.prior\.kind"):
        Scenario.from_dict({"prior": {"kind": "psychic"}})
    with pytest.raises(ConfigError, match=r"scenario\.prior\.power"):
        Scenario.from_dict({"prior": {"kind": "uninformed", "power": 2}})


def test_labels_and_round_trip():
    scenario = Scenario.from_dict({"prior": {"kind": "misweighted", "severity": 0.5, "variance_scale": 1.0},
                                   "targets": {"kind": "off_prior", "severity": 0.25}})  # fmt: skip
    assert scenario.label == "var1+misweighted0.5+off_prior0.25"
    assert Scenario.from_dict(scenario.to_dict()) == scenario
    assert Scenario.from_dict({"obstacles": {"kind": "iid"}, "targets": {"kind": "prior"}}) == PAPER  # old records


def test_a_mix_picks_a_family_then_draws_that_scenarios_world():

    mix = Scenario.from_dict(group_option("scenario", "mixed_priors"))
    # per sharpness: the prior right (once per severity, so it is picked as often as a family) and 7 families x 3
    assert len(mix.scenarios) == 2 * (3 + 7 * 3) and mix.family == "mix" and not mix.targets_follow_prior
    assert sum(s.severity == 0 for s in mix.scenarios) == 6
    for seed in range(4):  # one integer picks the scenario; the rest of the reset is that scenario's
        rng = np.random.default_rng(seed)
        picked = mix.scenarios[int(rng.integers(len(mix.scenarios)))]
        want = allocate(CONFIG, 1)
        reset_world(CONFIG, want, 0, rng, picked)
        got = allocate(CONFIG, 1)
        reset_world(CONFIG, got, 0, np.random.default_rng(seed), mix)
        np.testing.assert_array_equal(got.target_pos, want.target_pos)
        np.testing.assert_array_equal(got.p, want.p)
    walls = Scenario.from_dict(group_option("scenario", "mixed_walls"))
    assert [s.label for s in walls.scenarios] == ["paper", "iid0.2c", "primal", "maze3l0.1", "rooms12d3"]
    with pytest.raises(ConfigError, match=r"scenario\.targets is not allowed with scenario\.mix"):
        Scenario.from_dict({"mix": {"families": {}}, "targets": {"kind": "prior"}})


@pytest.mark.parametrize("severity", [0.5, 1.0])
def test_the_uninformed_prior_changes_what_the_agents_hold_never_the_truth(severity):
    """The targets follow p and u unchanged (truth_p is p and truth_u is u, bit for bit); the agents' u is the
    truth's too, and their p is (1 − s)·p + s/n²."""
    config = WorldConfig(world_size=(12, 12))
    rng = np.random.default_rng(3)
    p, u = rng.random((12, 12)), rng.random((12, 12))
    p, u = p / p.sum(), u / u.sum()
    draw = UninformedPrior(severity=severity).wrong(config, p, u, np.ones(4), np.random.default_rng(0))
    assert draw.truth_p.tobytes() == p.tobytes() and draw.truth_u.tobytes() == u.tobytes()
    assert draw.u.tobytes() == u.tobytes()
    np.testing.assert_allclose(draw.p, (1 - severity) * p + severity / 144)
