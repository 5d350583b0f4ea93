"""Heuristic controllers do what defines them: surfing climbs information and avoids agents; coverage sweeps."""

from __future__ import annotations

import numpy as np
import pytest

from searchrl.controllers.base import RandomWalk
from searchrl.controllers.coverage import GeometricCoverage, partition, sweep
from searchrl.controllers.surfing import InformationSurfing
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.observe import observe
from searchrl.world.state import allocate
from searchrl.world.step import step

E, W, N_, S = 2, 4, 1, 3


def _world(n: int, positions: list[tuple[int, int]], config: WorldConfig):
    """A hand-made world: no targets found yet, beliefs set by the caller."""
    state = allocate(config, 1)
    h = state.halo
    state.size[0] = n
    state.blocked[0] = True
    state.blocked[0, h : h + n, h : h + n] = False
    state.occupant[0] = -1
    for i, (r, c) in enumerate(positions):
        state.pos[0, i] = (r, c)
        state.occupant[0, r + h, c + h] = i
    state.n_targets[0] = 1
    state.target_valid[0, 0] = True
    state.obs_scale[0] = (1.0, 1.0)
    return state


@pytest.mark.parametrize("direction, action", [("east", E), ("west", W), ("south", S), ("north", N_)])
def test_surfing_climbs_a_known_gradient(direction, action):
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(30, [(15, 15)], config)
    h, ramp = state.halo, np.linspace(0.0, 1.0, 30, dtype=np.float32)
    field = {"east": ramp[None, :], "west": ramp[::-1][None, :], "south": ramp[:, None], "north": ramp[::-1, None]}
    state.belief[0, 0, :, h : h + 30, h : h + 30] = np.broadcast_to(field[direction], (30, 30))
    ctrl = InformationSurfing(config)
    maps, vector = observe(config, state)
    assert ctrl.act(state, maps, vector)[0, 0] == action


def test_surfing_moves_away_from_a_close_agent_on_flat_information():
    config = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))
    state = _world(30, [(15, 15), (15, 13)], config)  # agent 1 two cells west of agent 0; beliefs all zero
    ctrl = InformationSurfing(config)
    actions = ctrl.act(state, *observe(config, state))
    assert actions[0, 0] == E and actions[0, 1] == W


def test_surfing_does_not_step_into_a_visible_agent():
    config = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))
    state = _world(30, [(15, 15), (15, 16)], config)
    h = state.halo
    state.belief[0, 0, :, h : h + 30, h : h + 30] = np.linspace(0, 1, 30, dtype=np.float32)[None, :]
    action = InformationSurfing(config, repulsion=0.0).act(state, *observe(config, state))[0, 0]
    assert action != E and action != 0


def test_surfing_weighs_probability_and_uncertainty_as_told():
    """p rises east and u rises west: w_u = 0 (allowed) climbs p, w_p = 0 climbs u."""
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(30, [(15, 15)], config)
    h, ramp = state.halo, np.linspace(0.0, 1.0, 30, dtype=np.float32)
    state.belief[0, 0, 0, h : h + 30, h : h + 30] = ramp[None, :]
    state.belief[0, 0, 1, h : h + 30, h : h + 30] = ramp[::-1][None, :]
    for w_p, w_u, action in [(1.0, 0.0, E), (0.0, 1.0, W)]:
        assert InformationSurfing(config, w_p=w_p, w_u=w_u).act(state, *observe(config, state))[0, 0] == action


def test_surfing_follows_information_beyond_its_view_only_at_wider_scales():
    """Information only 16-40 cells west: the default scales (1, 3) see no gradient and move at random (as on an
    empty belief), scales (27,) head west."""
    config = WorldConfig(world_size=(60, 60), n_agents=1, n_targets=(1, 1))
    state, empty = _world(60, [(30, 45)], config), _world(60, [(30, 45)], config)
    h = state.halo
    state.belief[0, 0, :, h + 20 : h + 41, h + 5 : h + 30] = 1.0
    assert InformationSurfing(config, scales=(27,)).act(state, *observe(config, state))[0, 0] == W
    draws = [InformationSurfing(config, seed=5).act(s, *observe(config, s))[0, 0] for s in (state, empty)]
    assert draws[0] == draws[1]


@pytest.mark.parametrize("where, action", [((15, 10), E), ((15, 20), W), ((10, 15), S), ((20, 15), N_)])
def test_surfing_is_pushed_by_a_neighbour_at_the_edge_of_its_view(where, action):
    config = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))  # view 11×11: 5 cells each way
    state = _world(30, [(15, 15), where], config)
    assert InformationSurfing(config).act(state, *observe(config, state))[0, 0] == action


def test_surfing_moves_at_random_with_nothing_to_follow_and_repeats_with_its_seed():
    """The default seed is 0, as every controller's."""
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(30, [(15, 15)], config)
    draws = [[c.act(state, *observe(config, state))[0, 0] for _ in range(40)]
             for c in (InformationSurfing(config), InformationSurfing(config, seed=0),
                       InformationSurfing(config, seed=1))]  # fmt: skip
    assert draws[0] == draws[1] != draws[2]
    assert set(draws[0]) == {N_, E, S, W}


@pytest.mark.parametrize("kwargs, message", [
    ({"scales": []}, "scales=[] is not allowed: one or more positive block sizes"),
    ({"scales": [1, 0]}, "scales=[1, 0] is not allowed: one or more positive block sizes"),
    ({"w_p": -0.1}, "w_p=-0.1, w_u=0.4, repulsion=0.4 are not allowed: finite, >= 0, w_p + w_u > 0"),
    ({"w_u": float("inf")}, "w_p=0.6, w_u=inf, repulsion=0.4 are not allowed: finite, >= 0, w_p + w_u > 0"),
    ({"repulsion": -1.0}, "w_p=0.6, w_u=0.4, repulsion=-1.0 are not allowed: finite, >= 0, w_p + w_u > 0"),
    ({"w_p": float("inf")}, "w_p=inf, w_u=0.4, repulsion=0.4 are not allowed: finite, >= 0, w_p + w_u > 0"),
    ({"repulsion": float("inf")}, "w_p=0.6, w_u=0.4, repulsion=inf are not allowed: finite, >= 0, w_p + w_u > 0"),
    ({"w_p": 0.0, "w_u": 0.0}, "w_p=0.0, w_u=0.0, repulsion=0.4 are not allowed: finite, >= 0, w_p + w_u > 0"),
])  # fmt: skip
def test_surfings_bad_parameters_are_refused_in_one_line(kwargs, message):
    with pytest.raises(ValueError) as error:
        InformationSurfing(WorldConfig(), **kwargs)
    assert str(error.value) == message


def test_surfing_takes_equal_weights_and_no_repulsion():
    InformationSurfing(WorldConfig(), w_p=0.5, w_u=0.5, repulsion=0.0)


def test_partition_tiles_the_domain():
    for n, agents in [(20, 1), (20, 3), (40, 7), (160, 256)]:
        blocks = partition(n, agents)
        assert len(blocks) == agents
        cover = np.zeros((n, n), int)
        for r0, r1, c0, c1 in blocks:
            cover[r0:r1, c0:c1] += 1
        assert (cover == 1).all()
    # ceil(√N) rows of blocks, the first N mod rows rows one block longer
    assert partition(10, 2) == [(0, 5, 0, 10), (5, 10, 0, 10)]
    assert partition(12, 3) == [(0, 6, 0, 6), (0, 6, 6, 12), (6, 12, 0, 12)]
    assert [len({b[0] for b in partition(30, n)}) for n in (1, 2, 4, 5, 9, 10)] == [1, 2, 2, 3, 3, 4]


@pytest.mark.parametrize("n, agents, radius", [(12, 1, 1), (16, 4, 1), (20, 3, 2), (15, 2, 0)])
def test_coverage_brings_every_cell_within_radius_inside_the_sweep_bound(n, agents, radius):
    config = WorldConfig(world_size=(n, n), n_agents=agents, n_targets=(1, 1), max_steps=10_000)
    world = SearchWorld(config, 1, seed=1)
    maps, vector = world.reset()
    state = world.state
    ctrl = GeometricCoverage(config, radius=radius)
    ctrl.reset(state, np.ones(1, bool))
    # The bound the plan implies: walk to the first waypoint, then follow the waypoints (Manhattan lengths).
    bound = 0
    for i, block in enumerate(partition(n, agents)):
        plan = sweep(block, tuple(state.pos[0, i]), radius)
        legs = np.abs(np.diff(np.vstack([state.pos[0, i], plan]), axis=0)).sum()
        bound = max(bound, int(legs))
    seen = np.zeros((n, n), bool)
    rng = np.random.default_rng(0)
    for _ in range(bound):
        for r, c in state.pos[0]:
            seen[max(r - radius, 0) : r + radius + 1, max(c - radius, 0) : c + radius + 1] = True
        # The functional step keeps going after the target is found: targets do not matter to a sweep.
        step(config, state, ctrl.act(state, maps, vector), rng)
    for r, c in state.pos[0]:
        seen[max(r - radius, 0) : r + radius + 1, max(c - radius, 0) : c + radius + 1] = True
    assert seen.all(), f"cells never within radius {radius}: {np.argwhere(~seen)[:5].tolist()}"


def test_random_walk_is_uniform():
    config = WorldConfig(world_size=(10, 10), n_agents=4, diagonal=True)
    state = allocate(config, 50)
    actions = RandomWalk(config, seed=0).act(state, None, None)
    assert actions.shape == (50, 4) and set(np.unique(actions)) == set(range(9))


def test_coverage_agents_meeting_head_on_pass_each_other():
    """Two agents in one row heading for each other's cell: keeping right, both arrive (no deadlock)."""
    config = WorldConfig(world_size=(10, 10), n_agents=2, n_targets=(1, 1), max_steps=10_000)
    state = _world(10, [(5, 1), (5, 8)], config)
    ctrl = GeometricCoverage(config)
    ctrl.reset(state, np.ones(1, bool))
    ctrl.waypoints[0, 0, :2] = [(5, 8), (5, 8)]
    ctrl.waypoints[0, 1, :2] = [(5, 1), (5, 1)]
    ctrl.n_points[:] = 2
    ctrl.index[:] = 0
    rng = np.random.default_rng(0)
    reached = [False, False]
    for _ in range(30):
        step(config, state, ctrl.act(state, None, None), rng)
        reached[0] |= tuple(state.pos[0, 0]) == (5, 8)
        reached[1] |= tuple(state.pos[0, 1]) == (5, 1)
    assert all(reached), state.pos[0].tolist()


def test_the_switch_that_never_switches_is_bs_teacher_move_for_move():
    """threshold=0 never leaves the prior: every move is target-greedy's with reach 2 and the same seed (the shipped
    policies' teacher), so the rule's greedy half is that teacher and no other setting of it."""
    from searchrl.controllers.registry import make_controller
    from searchrl.controllers.switch import EvidenceSwitch

    config = WorldConfig(world_size=(20, 30), n_agents=4, n_targets=(4, 8))
    worlds = [SearchWorld(config, n_worlds=6, seed=3) for _ in range(2)]
    rules = [EvidenceSwitch(config, threshold=0.0), make_controller("greedy_target", config, 0, {"reach": 2.0})]
    observations = [world.reset() for world in worlds]
    for world, rule in zip(worlds, rules, strict=True):
        rule.reset(world.state, np.ones(6, bool))
    for _ in range(24):
        moves = [rule.act(world.state, *obs) for world, rule, obs in zip(worlds, rules, observations, strict=True)]
        np.testing.assert_array_equal(moves[0], moves[1])
        steps = [world.step(m) for world, m in zip(worlds, moves, strict=True)]
        observations = [(tr.maps, tr.vector) for tr in steps]
    for threshold in (0.0, 1.0):
        EvidenceSwitch(config, threshold=threshold)  # both ends allowed
    for bad in (-0.1, 1.5):
        with pytest.raises(ValueError, match=rf"^threshold={bad} is not allowed: 0 <= threshold <= 1 \(0: never"):
            EvidenceSwitch(config, threshold=bad)


def test_the_switch_moves_at_random_as_its_seed_says_where_nothing_is_left_to_sense():
    from searchrl.controllers.registry import make_controller
    from searchrl.controllers.switch import EvidenceSwitch

    config = WorldConfig(world_size=(30, 30), n_agents=3, n_targets=(1, 1))
    state = _world(30, [(5, 5), (15, 15), (25, 25)], config)  # beliefs all zero: greedy falls back to random moves
    state.p[0], state.u[0] = 1.0, 0.5  # the prior the switch weighs its evidence by; the agents' beliefs stay 0
    state.u[0, 0, 0] = 1.0  # in the wall around the world: the free cells' density p·(1 − u/max u) is 0.5
    for seed in (None, 5):  # the switch's default seed (0), and one given
        teacher = make_controller("greedy_target", config, seed or 0, {"reach": 2.0})
        switch = EvidenceSwitch(config, threshold=0.0) if seed is None else EvidenceSwitch(config, 0.0, seed=seed)
        for rule in (teacher, switch):
            rule.reset(state, np.ones(1, bool))
        moves = [[rule.act(state, *observe(config, state)) for _ in range(8)] for rule in (teacher, switch)]
        np.testing.assert_array_equal(moves[0], moves[1])
        assert len({tuple(m.ravel()) for m in moves[0]}) > 1  # random moves, drawn from the seed's stream


@pytest.mark.parametrize(
    "block, start, radius, waypoints",
    [
        ((0, 10, 0, 8), (0, 0), 2, [(2, 0), (2, 7), (7, 7), (7, 0)]),  # lanes 2 apart from the edges, 5 apart
        ((0, 10, 0, 8), (9, 7), 2, [(7, 7), (7, 0), (2, 0), (2, 7)]),  # from the far corner: both orders reversed
        ((0, 12, 0, 6), (0, 0), 2, [(2, 0), (2, 5), (7, 5), (7, 0), (9, 0), (9, 5)]),  # one more lane for the rest
        ((0, 3, 0, 5), (0, 4), 2, [(1, 4), (1, 0)]),  # thinner than two lanes' reach: one lane through the middle
        ((0, 9, 0, 9), (4, 4), 1, [(1, 0), (1, 8), (4, 8), (4, 0), (7, 0), (7, 8)]),  # ties keep the first lane, left
        ((10, 19, 20, 29), (18, 28), 1, [(17, 28), (17, 20), (14, 20), (14, 28), (11, 28), (11, 20)]),  # offset
        ((10, 19, 20, 29), (10, 20), 1, [(11, 20), (11, 28), (14, 28), (14, 20), (17, 20), (17, 28)]),  # its corner
        ((0, 10, 0, 8), (9, 0), 2, [(7, 0), (7, 7), (2, 7), (2, 0)]),  # the bottom lane first, from the left
        ((5, 6, 0, 4), (5, 0), 1, [(5, 0), (5, 3)]),  # a block one row high: one lane, on it
    ],
)
def test_a_sweep_is_a_boustrophedon_from_the_nearest_corner(block, start, radius, waypoints):
    np.testing.assert_array_equal(sweep(block, start, radius), np.array(waypoints, np.int64).reshape(-1, 2))


def test_one_coverage_controller_serves_worlds_of_another_batch_and_moves_diagonally_in_the_diagonal_model():
    ctrl = GeometricCoverage(WorldConfig(world_size=(20, 20), n_targets=(1, 1)))
    for k, n in ((1, 2), (3, 3), (2, 1)):  # batches of other K and N: each reset plans for the worlds it is given
        config = WorldConfig(world_size=(20, 20), n_agents=n, n_targets=(1, 1))
        world = SearchWorld(config, n_worlds=k, seed=k)
        world.reset()
        ctrl.reset(world.state, np.ones(k, bool))
        fresh = GeometricCoverage(config)
        fresh.reset(world.state, np.ones(k, bool))
        np.testing.assert_array_equal(
            ctrl.act(world.state, *world.observation), fresh.act(world.state, *world.observation)
        )
        assert ctrl.waypoints.dtype == ctrl.n_points.dtype == ctrl.index.dtype == np.int64  # the kernel's signature
    diagonal = WorldConfig(world_size=(20, 20), n_agents=1, n_targets=(1, 1), diagonal=True)
    state = _world(20, [(10, 10)], diagonal)  # its block is the whole world: the plan starts at the corner (1, 1)
    ctrl = GeometricCoverage(diagonal)
    ctrl.reset(state, np.ones(1, bool))
    assert ctrl.act(state, *observe(diagonal, state))[0, 0] >= 5  # a diagonal move (actions 5-8) toward it


def test_the_switch_weighs_the_prior_by_where_targets_are_kept():
    """density t = p·(1 − u/max u) on free cells, 0 on walls, summing to 1 per world (§4.1.4's placement)."""
    from searchrl.controllers.switch import EvidenceSwitch

    config = WorldConfig(world_size=(12, 12), n_agents=1, n_targets=(1, 1))
    state = _world(12, [(3, 3)], config)
    rng = np.random.default_rng(0)
    state.p[0], state.u[0] = rng.random(state.p.shape[1:]), rng.random(state.u.shape[1:])
    switch = EvidenceSwitch(config)
    switch.reset(state, np.ones(1, bool))
    t = np.where(state.blocked[0], 0.0, state.p[0] * (1.0 - state.u[0] / state.u[0].max()))
    np.testing.assert_allclose(switch.density[0], t / t.sum(), rtol=1e-6)


def test_the_switch_counts_what_the_footprints_swept_and_then_sweeps_by_coverage():
    """expected = Σ density·(1 − left): one footprint in a world of uniform density sweeps ΣΓ / (free cells) of it.
    With the prior promising 1,000 targets and none found, the switch leaves the prior at once and its agents take
    coverage's moves from the plan made at the world's start, in a first episode and after a reset."""
    from searchrl.controllers.switch import EvidenceSwitch
    from searchrl.world.footprint import SUPPORT_G

    config = WorldConfig(world_size=(12, 12), n_agents=1, n_targets=(1, 1))
    state = _world(12, [(6, 6)], config)
    state.p[0], state.u[0], state.u[0, 0, 0] = 1.0, 0.5, 1.0  # uniform density over the 144 free cells
    switch = EvidenceSwitch(config, threshold=0.0)  # never switches: the count alone
    switch.reset(state, np.ones(1, bool))
    switch.act(state, *observe(config, state))
    np.testing.assert_allclose(switch.expected(), [SUPPORT_G.sum() / 144])
    state.n_targets[0] = 1000
    switch = EvidenceSwitch(config, threshold=1.0)
    for start in ((6, 6), (2, 9)):
        state.occupant[0] = -1
        state.pos[0, 0] = start
        state.occupant[0, start[0] + state.halo, start[1] + state.halo] = 0
        switch.reset(state, np.ones(1, bool))
        coverage = GeometricCoverage(config)
        coverage.reset(state, np.ones(1, bool))
        moves = switch.act(state, *observe(config, state))
        assert switch.switched.all()
        np.testing.assert_array_equal(moves, coverage.act(state, *observe(config, state)))


def test_the_switch_weighs_each_world_by_its_own_prior():
    from searchrl.controllers.switch import EvidenceSwitch

    config = WorldConfig(world_size=(12, 12), n_agents=1, n_targets=(1, 1))
    state = allocate(config, 2)
    h = state.halo
    state.size[:] = 12
    state.blocked[:] = True
    state.blocked[:, h : h + 12, h : h + 12] = False
    rng = np.random.default_rng(1)
    state.p[:], state.u[:] = rng.random(state.p.shape), rng.random(state.u.shape)
    state.p[1] *= 5.0
    state.u[1] *= 3.0  # another scale of p and u in world 1: each world's density is its own
    switch = EvidenceSwitch(config)
    switch.reset(state, np.ones(2, bool))
    for k in range(2):
        t = np.where(state.blocked[k], 0.0, state.p[k] * (1.0 - state.u[k] / state.u[k].max()))
        np.testing.assert_allclose(switch.density[k], t / t.sum(), rtol=1e-6)


def test_the_switch_judges_at_its_threshold_once_two_detections_were_due_and_keeps_its_verdict():
    """A world switches once expected ≥ 2 and (found + 1) / (expected + 1) < threshold, expected being the targets
    the prior promised times the share of its density the team swept, and stays switched when the finds catch up.
    The density sits on one cell, half swept and out of the agent's way: 4 targets promised make expected 2 exactly."""
    from searchrl.controllers.switch import EvidenceSwitch

    config = WorldConfig(world_size=(12, 12), n_agents=1, n_targets=(1, 1))
    state = _world(12, [(2, 2)], config)
    state.p[0], state.u[0], state.u[0, 0, 0] = 1.0, 0.5, 1.0  # a density the test then replaces
    cell = (state.halo + 9, state.halo + 9)  # 7 cells from the agent: no footprint of it reaches there

    def judged(threshold: float, promised: int, found: int) -> EvidenceSwitch:
        switch = EvidenceSwitch(config, threshold)
        switch.reset(state, np.ones(1, bool))
        switch.density[0], switch.left[0][cell] = 0.0, 0.5
        switch.density[0][cell] = 1.0
        state.n_targets[0], state.n_found[0] = promised, found
        switch.act(state, *observe(config, state))
        return switch

    # (threshold, promised, found) -> switched: 1/3 against 0.3 and 0.5; 1/2 but only one detection due; 1/4 exactly
    cases = {(0.3, 4, 0): False, (0.5, 4, 0): True, (1.0, 2, 0): False, (0.25, 6, 0): False, (0.26, 6, 0): True}
    for (threshold, promised, found), switched in cases.items():
        assert judged(threshold, promised, found).switched[0] == switched, (threshold, promised, found)
    switch = judged(0.5, 4, 0)
    state.n_found[0] = 3  # (3 + 1) / (2 + 1): no longer behind, but a verdict is for good
    switch.act(state, *observe(config, state))
    assert switch.switched[0]


def test_the_switch_acts_before_a_reset_as_after_one_and_only_switched_worlds_take_coverage():
    from searchrl.controllers.registry import make_controller
    from searchrl.controllers.switch import EvidenceSwitch

    config = WorldConfig(world_size=(20, 20), n_agents=3, n_targets=(4, 6))
    world = SearchWorld(config, n_worlds=2, seed=4)
    maps, vector = world.reset()
    fresh, reset_first = EvidenceSwitch(config, 0.5, seed=2), EvidenceSwitch(config, 0.5, seed=2)
    reset_first.reset(world.state, np.ones(2, bool))
    np.testing.assert_array_equal(fresh.act(world.state, maps, vector), reset_first.act(world.state, maps, vector))

    switch, teacher = EvidenceSwitch(config, 0.5, seed=2), make_controller("greedy_target", config, 2, {"reach": 2.0})
    coverage = GeometricCoverage(config)
    for rule in (switch, teacher, coverage):
        rule.reset(world.state, np.ones(2, bool))
    switch.switched[0] = True  # world 0 has left the prior; world 1's first footprints promise less than 2 finds
    moves = switch.act(world.state, maps, vector)
    np.testing.assert_array_equal(moves[0], coverage.act(world.state, maps, vector)[0])
    np.testing.assert_array_equal(moves[1], teacher.act(world.state, maps, vector)[1])
    assert moves.dtype == np.int64 and not switch.switched[1]
