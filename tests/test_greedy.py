"""Footprint-greedy takes the move whose footprint would sense the most information it can see."""

from __future__ import annotations

import math

import numpy as np
import pytest

from searchrl.controllers.greedy import FootprintGreedy
from searchrl.controllers.greedy_kernels import reach_weights
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import GAMMA
from searchrl.world.observe import observe
from searchrl.world.reset import reset_worlds
from searchrl.world.state import allocate
from searchrl.world.step import step
from tests.handmade import make_world

N_, E, S, W = 1, 2, 3, 4
OFFSETS = {N_: (-1, 0), E: (0, 1), S: (1, 0), W: (0, -1)}


def _world(config: WorldConfig, positions: list[tuple[int, int]]):
    """A 30×30 world with zero beliefs (the caller adds information), agents at `positions`, one target in a corner."""
    return make_world(config, 30, positions, targets=[(0, 0)])


def _put(state, agent: int, r: int, c: int, value: float = 1.0) -> None:
    h = state.halo
    state.belief[0, agent, :, r + h, c + h] = value


def _act(ctrl: FootprintGreedy, state) -> np.ndarray:
    return ctrl.act(state, *observe(ctrl.config, state))[0]


@pytest.mark.parametrize("action", [N_, E, S, W])
def test_greedy_heads_for_information_in_view(action):
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(config, [(15, 15)])
    dr, dc = OFFSETS[action]
    _put(state, 0, 15 + 3 * dr, 15 + 3 * dc)
    assert _act(FootprintGreedy(config), state)[0] == action


def test_greedy_ignores_information_outside_the_field_of_view():
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(config, [(15, 15)])
    _put(state, 0, 15, 21, 100.0)  # 6 cells east: outside the 11×11 view
    _put(state, 0, 15, 12, 0.01)  # a little information 3 cells west, inside it
    assert _act(FootprintGreedy(config), state)[0] == W


def test_horizon_sets_how_far_ahead_a_move_is_scored():
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(config, [(15, 15)])
    _put(state, 0, 15, 19)  # 4 cells east: the footprint reaches it after two steps east, not after one
    _put(state, 0, 17, 15, 0.05)  # weaker information 2 cells south, in reach after one step
    assert _act(FootprintGreedy(config, horizon=1), state)[0] == S
    assert _act(FootprintGreedy(config, horizon=2), state)[0] == E


def test_greedy_does_not_step_into_an_agent():
    config = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))
    state = _world(config, [(15, 15), (15, 16)])
    _put(state, 0, 15, 17)
    assert _act(FootprintGreedy(config), state)[0] not in (0, E)


def test_greedy_moves_at_random_with_nothing_to_sense_and_repeats_with_its_seed():
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(config, [(15, 15)])
    draws = [[_act(ctrl, state)[0] for _ in range(40)] for ctrl in (FootprintGreedy(config, seed=3),
                                                                     FootprintGreedy(config, seed=3))]  # fmt: skip
    assert draws[0] == draws[1]
    assert set(draws[0]) == {N_, E, S, W}


def test_greedy_uses_diagonal_moves_in_the_diagonal_model():
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1), diagonal=True)
    state = _world(config, [(15, 15)])
    _put(state, 0, 12, 18)  # 3 cells north-east
    assert _act(FootprintGreedy(config), state)[0] == 5  # NE


@pytest.mark.parametrize("contested, other_col, action", [(1.0, 19, E), (0.0, 19, W), (0.0, 21, E)])
def test_contested_leaves_to_a_visible_neighbour_the_cells_it_reaches_first(contested, other_col, action):
    """Information 3 east of agent 0 and 1 west of agent 1 (4 east): with contested=0 agent 0 leaves it and goes for
    the weaker information west; an agent 6 east is outside the view and contests nothing."""
    config = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))
    state = _world(config, [(15, 15), (15, other_col)])
    _put(state, 0, 15, other_col - 1 if other_col == 19 else 19)  # nearer the other agent than agent 0
    _put(state, 0, 15, 15 - (3 if other_col == 19 else 4), 0.3)  # as far west as the information is east
    assert _act(FootprintGreedy(config, contested=contested), state)[0] == action


def test_target_weight_avoids_probability_under_high_uncertainty():
    """Equal p three cells east and west; east also has û = 0.9, where §4.1.4 rarely keeps a target. The blend
    0.6 p̂ + 0.4 û goes east for the uncertainty; w_t alone scores p̂ (1 − û) and goes west."""
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(config, [(15, 15)])
    h = state.halo
    state.belief[0, 0, 0, 15 + h, 18 + h] = state.belief[0, 0, 0, 15 + h, 12 + h] = 0.5
    state.belief[0, 0, 1, 15 + h, 18 + h] = 0.9
    assert _act(FootprintGreedy(config), state)[0] == E
    assert _act(FootprintGreedy(config, w_p=0.0, w_u=0.0, w_t=1.0), state)[0] == W


def test_reach_weights_count_cells_by_the_footprint_mass_that_can_reach_them():
    """Γ_total / Γ_reach: 1 inside, 5.44/3.96 on an edge, 5.44/2.85 in a corner, above 1 beside an obstacle,
    0 on blocked cells; the exponent raises them."""
    blocked = np.ones((1, 24, 24), bool)
    blocked[0, 5:19, 5:19] = False  # a 14×14 world with a halo of 5
    blocked[0, 12, 12] = True  # one obstacle
    total = GAMMA.sum()
    weights = reach_weights(blocked, 1.0)[0]
    assert weights[8, 8] == pytest.approx(1.0)
    assert weights[5, 8] == pytest.approx(total / (total - GAMMA[3:].sum()))  # top edge: no agent above it
    assert weights[5, 5] == pytest.approx(total / (total - GAMMA[3:].sum() - GAMMA[:3, 3:].sum()))
    assert weights[12, 13] > 1.0 and weights[12, 12] == 0.0 and weights[0, 0] == 0.0
    assert np.allclose(reach_weights(blocked, 2.0)[0], weights**2)
    assert np.array_equal(reach_weights(blocked, 0.0)[0], (~blocked[0]).astype(float))


def test_reach_draws_to_the_edge_what_passing_agents_would_barely_sense():
    """Information 0.9 on the west edge and 1.0 as far east, reached with the same footprint weights: every cell
    counting the same goes east; reach 1 weighs the edge cell by 5.44/3.96 and goes west."""
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(config, [(15, 3)])
    _put(state, 0, 15, 0, 0.9)
    _put(state, 0, 15, 6, 1.0)
    assert _act(FootprintGreedy(config), state)[0] == E
    assert _act(FootprintGreedy(config, reach=1.0), state)[0] == W


def test_prior_information_is_the_mean_information_of_the_free_cells():
    """What `hedge` mixes in: I = w_p·p̂ + w_u·û + w_t·p̂·max(0, 1 − û) of the prior, as the observation scales it,
    averaged over the free cells (an obstacle's prior does not count)."""
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    rng = np.random.default_rng(2)
    p, u = rng.uniform(0.1, 1.0, (30, 30)), rng.uniform(0.1, 1.5, (30, 30))
    state = make_world(config, 30, [(15, 15)], [(0, 0)], obstacles=((3, 4), (20, 7)), p=p, u=u)
    state.obs_scale[0] = (2.0, 0.5)
    free = np.ones((30, 30), bool)
    free[3, 4] = free[20, 7] = False
    p_hat, u_hat = p * 2.0, u * 0.5
    info = 0.2 * p_hat + 0.3 * u_hat + 0.5 * p_hat * np.maximum(0.0, 1.0 - u_hat)
    got = FootprintGreedy(config, w_p=0.2, w_u=0.3, w_t=0.5).prior_information(state)
    np.testing.assert_allclose(got, [info[free].mean()], rtol=1e-6)


@pytest.mark.parametrize("bulk, action", [(0.05, W), (0.5, E)])
def test_hedge_weighs_what_sensing_left_by_the_priors_mean_information(bulk, action):
    """With hedge ε a cell counts (1 − ε)·I + ε·flat·p/prior_p, flat the prior's mean I per free cell. West: belief
    1 of prior 1; east: belief 0.5 of prior 0.1; elsewhere belief 0 of prior `bulk`, which sets flat. At ε = 0.5
    west scores 0.5 + 0.5·flat, east 0.25 + 2.5·flat: west below flat ≈ 0.125, east above (seeds 0-7 alike)."""
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    prior = np.full((30, 30), bulk)
    prior[15, 12], prior[15, 18] = 1.0, 0.1
    state = make_world(config, 30, [(15, 15)], [(0, 0)], p=prior)
    h = state.halo
    state.belief[0, 0, 0] = 0.0
    state.belief[0, 0, 0, 15 + h, 12 + h], state.belief[0, 0, 0, 15 + h, 18 + h] = 1.0, 0.5
    assert [_act(FootprintGreedy(config, w_p=1.0, w_u=0.0, seed=s), state)[0] for s in range(8)] == [W] * 8
    hedged = [_act(FootprintGreedy(config, w_p=1.0, w_u=0.0, hedge=0.5, seed=s), state)[0] for s in range(8)]
    assert hedged == [action] * 8


def test_greedy_follows_a_team_of_another_size_without_a_reset():
    """A controller that acted on a team of two and then meets a team of four on the same ground sizes its
    memory again and acts as a fresh one (information everywhere, so nobody moves at random)."""
    ramp = np.linspace(0.1, 1.0, 30)[None, :] * np.linspace(0.5, 1.0, 30)[:, None]
    config2 = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))
    config4 = WorldConfig(world_size=(30, 30), n_agents=4, n_targets=(1, 1))
    two = make_world(config2, 30, [(5, 5), (20, 20)], [(0, 0)], p=ramp, u=ramp)
    four = make_world(config4, 30, [(5, 5), (20, 20), (10, 25), (25, 3)], [(0, 0)], p=ramp, u=ramp)
    kwargs = {"w_t": 1.0, "reach": 1.0, "seen": True}
    used = FootprintGreedy(config2, **kwargs)
    used.act(two, *observe(config2, two))
    fresh = FootprintGreedy(config4, **kwargs)
    assert (used.act(four, *observe(config4, four)) == fresh.act(four, *observe(config4, four))).all()


def test_a_smaller_team_after_a_larger_one_forgets_what_the_larger_saw():
    """Agent 0 of a team of four sees agent 2 three cells east and remembers its footprint there; a team of two on
    the same ground, without a reset, acts as a fresh controller: east (1.0) over west (0.9), not the remembered
    lowering."""
    config4 = WorldConfig(world_size=(30, 30), n_agents=4, n_targets=(1, 1))
    config2 = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))
    four = make_world(config4, 30, [(15, 15), (5, 5), (15, 18), (25, 25)], [(0, 0)])
    two = make_world(config2, 30, [(15, 15), (5, 5)], [(0, 0)])
    _put(two, 0, 15, 18, 1.0)
    _put(two, 0, 15, 12, 0.9)
    used = FootprintGreedy(config4, seen=True)
    used.act(four, *observe(config4, four))
    assert used.act(two, *observe(config2, two))[0, 0] == _act(FootprintGreedy(config2, seen=True), two)[0] == E


def test_seen_lowers_the_belief_under_a_neighbours_footprint_and_remembers_it():
    """Information 1.0 three cells east, on the cell where a neighbour stands, and 0.9 three west. Greedy goes east;
    with `seen` the neighbour's footprint clears that cell in what agent 0 believes, so it goes west, and it still
    does after the neighbour has left its view, until a reset forgets what it saw."""
    config = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))
    state = _world(config, [(15, 15), (15, 18)])
    _put(state, 0, 15, 18, 1.0)
    _put(state, 0, 15, 12, 0.9)
    assert _act(FootprintGreedy(config), state)[0] == E
    greedy = FootprintGreedy(config, seen=True)
    greedy.reset(state, np.ones(1, bool))
    assert _act(greedy, state)[0] == W
    h = state.halo
    state.occupant[0, 15 + h, 18 + h], state.occupant[0, 2 + h, 28 + h] = -1, 1  # agent 1 leaves the view
    state.pos[0, 1] = (2, 28)
    assert _act(greedy, state)[0] == W
    greedy.reset(state, np.ones(1, bool))
    assert _act(greedy, state)[0] == E


def test_age_prefers_what_the_agent_saw_lately_to_what_it_never_saw():
    """Information 1.0 three cells east that agent 0 has not seen since the start, and 0.4 two cells west, inside its
    explicit area Φ, so it knows that value is the truth now. Greedy goes east; with `age`, 100 steps on, what an
    evenly spread team would have sensed there since lowers the east cell to 0.55 of it, so it goes west, and a reset
    (step 0) makes both fresh again."""
    config = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))
    state = _world(config, [(15, 15)])
    _put(state, 0, 15, 18, 1.0)
    _put(state, 0, 15, 13, 0.4)
    state.t[:] = 100
    assert _act(FootprintGreedy(config), state)[0] == E
    greedy = FootprintGreedy(config, age=1.0)
    greedy.reset(state, np.ones(1, bool))
    assert _act(greedy, state)[0] == W
    state.t[:] = 0
    greedy.reset(state, np.ones(1, bool))
    assert _act(greedy, state)[0] == E


def test_the_worlds_belief_seen_shows_what_greedy_with_age_and_seen_scores():
    """`env.world.belief_seen` exists so that a clone sees the factor its teacher (greedy with `age` and `seen`)
    scales its belief by: along a crowded episode, channel 5 of every agent's view equals that factor."""
    config = WorldConfig(world_size=(16, 24), n_agents=24, communication=False, belief_age=0.5,
                         belief_age_channel=True, belief_seen=True)  # fmt: skip
    state = allocate(config, 2)
    reset_worlds(config, state, np.ones(2, bool), np.random.default_rng(3))
    greedy = FootprintGreedy(config, age=0.5, seen=True, seed=4)
    rng, view, h = np.random.default_rng(5), config.fov // 2, state.halo
    lowered = 0
    for _ in range(30):
        maps, vec = observe(config, state)
        actions = greedy.act(state, maps, vec)  # updates what greedy remembers, at this step's positions
        rates = greedy._rates[:, None, None, None]
        factor = np.exp(-rates * (state.t[:, None, None, None] - greedy._known)) * greedy._seen
        for k in range(2):
            for i in range(config.n_agents):
                r, c = state.pos[k, i] + h
                window = factor[k, i, r - view : r + view + 1, c - view : c + view + 1]
                np.testing.assert_allclose(maps[k, i, 5], window, rtol=1e-5, atol=1e-7)
        lowered += int((greedy._seen < 1).sum())
        step(config, state, actions, rng)
    assert lowered > 0  # neighbours were seen, so the check covered the seen factor


BAD = [({"horizon": 0}, "horizon"), ({"horizon": 6}, "horizon"), ({"discount": 0.0}, "discount"),
       ({"w_p": 0.0, "w_u": 0.0}, "w_p"), ({"w_t": -1.0}, "w_t"), ({"contested": 1.5}, "contested"),
       ({"contested": -0.1}, "contested"), ({"reach": -1.0}, "reach"), ({"reach": 5.0}, "reach"),
       ({"age": -0.5}, "age"), ({"age": 5.0}, "age"), ({"discount": 1.5}, "discount"), ({"hedge": -0.1}, "hedge"),
       ({"hedge": 1.5}, "hedge"), ({"w_u": math.inf}, "w_u")]  # fmt: skip


@pytest.mark.parametrize("kwargs, name", BAD)
def test_bad_parameters_are_named(kwargs, name):
    with pytest.raises(ValueError, match=name):
        FootprintGreedy(WorldConfig(), **kwargs)


EDGES = [{"horizon": 5}, {"discount": 1.0}, {"reach": 4.0}, {"age": 4.0}, {"hedge": 1.0},
         {"w_p": 0.0, "w_u": 1.0, "w_t": 1.0}, {"w_p": 1.0, "w_u": 1.0, "w_t": 0.0}]  # fmt: skip


@pytest.mark.parametrize("kwargs", [{"seen": True}, {"age": 0.5}])
def test_seen_and_age_are_refused_where_sensing_is_not_bayesian(kwargs):
    config = WorldConfig(k=500.0)  # lam·k = 0.5: sensing no longer scales p by (1 − Γ)
    FootprintGreedy(config)  # the plain rule is fine there
    seen, age = kwargs.get("seen", False), kwargs.get("age", 0.0)
    with pytest.raises(ValueError) as error:
        FootprintGreedy(config, **kwargs)
    assert str(error.value) == (
        f"seen={seen!r}, age={age!r} are not allowed in this world: both model sensing as p·(1 − Γ), so they need "
        f"lam * k = 1 and k_per_n = 0 (here k={config.k}, k_per_n={config.k_per_n})"
    )


@pytest.mark.parametrize("kwargs", EDGES)
def test_the_edges_of_each_range_are_allowed(kwargs):
    FootprintGreedy(WorldConfig(), **kwargs)  # 11×11 view: horizon up to 5


def _seen_without_age(state, seen: np.ndarray, view: int) -> None:
    """Greedy's `seen` without `age`, as a plain loop (the reference for the one difference from the world's):
    (1 − Γ) under every neighbour in view, scanned row by row, and never reset on Φ until the world is."""
    h, g = state.halo, GAMMA.shape[0] // 2
    for k in range(state.n_worlds):
        for i in range(state.n_agents):
            r, c = state.pos[k, i] + h
            for rr in range(r - view, r + view + 1):
                for cc in range(c - view, c + view + 1):
                    if state.occupant[k, rr, cc] not in (-1, i):
                        for dr in range(-g, g + 1):
                            for dc in range(-g, g + 1):
                                cell = seen[k, i, rr + dr, cc + dc]
                                seen[k, i, rr + dr, cc + dc] = np.float32(cell * (1.0 - GAMMA[dr + g, dc + g]))


@pytest.mark.parametrize("age", [0.0, 0.5])
def test_greedy_keeps_the_worlds_freshness_bit_for_bit(age):
    """One implementation (searchrl/world/seen.py) keeps both: with `age` greedy's seen and known equal the world's
    belief_seen and belief_time exactly, step by step and across resets; without it seen is never reset on Φ."""
    config = WorldConfig(world_size=(12, 20), n_agents=12, n_targets=(2, 4), communication=False, belief_age=0.5,
                         belief_seen=True, max_steps=25)  # fmt: skip
    state = allocate(config, 3)
    reset_worlds(config, state, np.ones(3, bool), np.random.default_rng(0))
    greedy = FootprintGreedy(config, age=age, seen=True, contested=0.5, seed=1)
    greedy.reset(state, np.ones(3, bool))
    reference, rng, resets = np.ones_like(state.belief_seen), np.random.default_rng(2), 0
    for _ in range(60):
        actions = greedy.act(state, *observe(config, state))
        _seen_without_age(state, reference, config.fov // 2)
        if age > 0:
            np.testing.assert_array_equal(greedy._seen, state.belief_seen)
            np.testing.assert_array_equal(greedy._known, state.belief_time)
        else:
            np.testing.assert_array_equal(greedy._seen, reference)
            assert greedy._known.size == 0
        done = step(config, state, actions, rng).done
        if done.any():
            resets += 1
            reset_worlds(config, state, done, rng)
            greedy.reset(state, done)
            reference[done] = 1.0
    assert resets > 0 and (reference < 1).any()
