"""Tiny hand-drawn worlds with numbers worked out by hand from SPEC.md and the paper (Table 1, eq. 1-5)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from searchrl.world.footprint import GAMMA
from searchrl.world.observe import observe
from searchrl.world.step import step
from tests.handmade import cfg, draws, make_world, seed_where

G1, G2, G4 = math.exp(-0.5), math.exp(-1.0), math.exp(-2.0)  # Γ at distance 1, √2 and 2 (§3.1)
SUM_GAMMA = 1.0 + 4 * (G1 + G2 + G4)  # the 13 non-zero cells of Γ
STAY, N, E, S, W, SE, NW = 0, 1, 2, 3, 4, 6, 8


def act(*a: int) -> np.ndarray:
    return np.array([a], np.int64)


def test_gamma_is_the_papers_matrix() -> None:
    paper = [
        [0, 0, 0.1353, 0, 0],
        [0, 0.3679, 0.6065, 0.3679, 0],
        [0.1353, 0.6065, 1.0, 0.6065, 0.1353],
        [0, 0.3679, 0.6065, 0.3679, 0],
        [0, 0, 0.1353, 0, 0],
    ]
    np.testing.assert_allclose(GAMMA, paper, atol=5e-5)


@pytest.mark.parametrize("seed", range(5))
def test_target_under_agent_is_found_whatever_the_draw(seed: int) -> None:
    config = cfg(max_steps=1)
    state = make_world(config, 7, agents=[(3, 3)], targets=[(3, 3)], p=1 / 49, u=1 / 49)
    res = step(config, state, act(STAY), np.random.default_rng(seed))
    assert res.targets_found[0, 0] == 1 and state.n_found[0] == 1 and state.target_found[0, 0]
    assert state.found_grid[0, 3 + state.halo, 3 + state.halo] and state.found_grid[0].sum() == 1
    # λk = 1: every footprint cell keeps p(1 - Γ), so the agent collects (1/49)·ΣΓ from each map (eq. 1-4).
    m = SUM_GAMMA / 49
    np.testing.assert_allclose(res.info_collected[0, 0], 2 * m, rtol=1e-6)
    np.testing.assert_allclose(res.reward[0, 0], -0.05 + 10.0 + (0.05 / 0.001) * 2 * m, rtol=1e-6)
    assert state.p[0, 3 + state.halo, 3 + state.halo] == 0.0  # Γ = 1 under the agent empties the cell
    # All targets found at the last allowed step: terminated, and never truncated at the same time.
    assert res.terminated[0] and not res.truncated[0] and state.t[0] == 1


@pytest.mark.parametrize("lucky", [True, False])
def test_target_at_distance_two_found_iff_draw_below_gamma(lucky: bool) -> None:
    config = cfg(max_steps=5)
    # Draws within 0.002 of Γ = e^-2 on either side, so a threshold that is off even slightly fails.
    seed = seed_where(lambda _, d: (G4 - 0.002 < d[0] < G4) if lucky else (G4 <= d[0] < G4 + 0.002), 1, 1)
    state = make_world(config, 7, agents=[(3, 3)], targets=[(3, 5)])
    res = step(config, state, act(STAY), np.random.default_rng(seed))
    assert bool(state.target_found[0, 0]) == lucky and res.targets_found[0, 0] == int(lucky)
    assert res.terminated[0] == lucky and not res.truncated[0]
    assert res.reward[0, 0] == np.float32(-0.05 + 10.0 * lucky)  # empty maps: no information term


@pytest.mark.parametrize("winner", [0, 1, None])
def test_two_covering_agents_detect_sequentially_in_index_order(winner: int | None) -> None:
    # Agent 0 is farther (Γ = e^-2) but is walked first; agent 1 (Γ = e^-0.5) gets the rest of 1 - Π(1 - g).
    config = cfg(n_agents=2)
    both = 1 - (1 - G4) * (1 - G1)
    outcome = {0: lambda d: d < G4, 1: lambda d: G4 <= d < both, None: lambda d: d >= both}[winner]
    seed = seed_where(lambda _, d: outcome(d[0]), 2, 1)
    state = make_world(config, 7, agents=[(3, 2), (2, 4)], targets=[(3, 4)])
    res = step(config, state, act(STAY, STAY), np.random.default_rng(seed))
    expected = [0, 0] if winner is None else [int(i == winner) for i in range(2)]
    np.testing.assert_array_equal(res.targets_found[0], expected)
    assert state.n_found[0] == sum(expected)


@pytest.mark.parametrize(
    ("start", "action", "obstacles", "diagonal"),
    [((0, 3), N, (), False), ((3, 0), W, (), False), ((6, 6), S, (), False), ((3, 3), E, ((3, 4),), False),
     ((0, 0), NW, (), True), ((6, 3), SE, (), True)],
)  # fmt: skip
def test_move_into_boundary_or_obstacle_is_blocked(start, action, obstacles, diagonal) -> None:
    config = cfg(diagonal=diagonal)
    far = (6, 0) if start[0] < 3 else (0, 6)  # no chance of a detection bonus
    state = make_world(config, 7, agents=[start], targets=[far], obstacles=obstacles)
    res = step(config, state, act(action), np.random.default_rng(0))
    assert res.collided[0, 0] and tuple(state.pos[0, 0]) == start
    assert res.reward[0, 0] == np.float32(-0.05 - 0.2) and state.ep_collisions[0] == 1


def test_diagonal_move_goes_diagonally() -> None:
    config = cfg(diagonal=True)
    state = make_world(config, 7, agents=[(3, 3)], targets=[(6, 0)])
    res = step(config, state, act(SE), np.random.default_rng(0))
    assert not res.collided[0, 0] and tuple(state.pos[0, 0]) == (4, 4)
    h = state.halo
    assert state.occupant[0, 4 + h, 4 + h] == 0 and state.occupant[0, 3 + h, 3 + h] == -1


@pytest.mark.parametrize("first_wins", [True, False])
def test_contest_for_a_cell_goes_to_higher_priority(first_wins: bool) -> None:
    config = cfg(n_agents=2)
    seed = seed_where(lambda pr, _: (pr[0] > pr[1]) == first_wins, 2, 1)
    state = make_world(config, 7, agents=[(3, 2), (3, 4)], targets=[(6, 6)])
    res = step(config, state, act(E, W), np.random.default_rng(seed))
    winner = 0 if first_wins else 1
    assert tuple(state.pos[0, winner]) == (3, 3)
    assert tuple(state.pos[0, 1 - winner]) == [(3, 2), (3, 4)][1 - winner]
    np.testing.assert_array_equal(res.collided[0], [not first_wins, first_wins])
    assert res.reward[0, 1 - winner] == np.float32(-0.25) and res.reward[0, winner] == np.float32(-0.05)


@pytest.mark.parametrize("seed", range(3))
def test_swap_is_blocked_for_both(seed: int) -> None:
    config = cfg(n_agents=2)
    state = make_world(config, 7, agents=[(3, 3), (3, 4)], targets=[(6, 6)])
    res = step(config, state, act(E, W), np.random.default_rng(seed))
    assert res.collided[0].all() and state.pos[0].tolist() == [[3, 3], [3, 4]]


def test_chain_and_stayer_block_the_follower() -> None:
    # Agent 0 follows agent 1 into the cell it leaves: blocked (occupied at the start of the step).
    # Agent 2 moves onto agent 3, which stays: blocked. Agent 1 moves freely.
    config = cfg(n_agents=4, n_targets=(1, 1))
    state = make_world(config, 7, agents=[(3, 2), (3, 3), (5, 1), (5, 2)], targets=[(0, 6)])
    res = step(config, state, act(E, E, E, STAY), np.random.default_rng(0))
    np.testing.assert_array_equal(res.collided[0], [True, False, True, False])
    assert state.pos[0].tolist() == [[3, 2], [3, 4], [5, 1], [5, 2]]


def test_overlapping_footprints_split_the_loss_by_gamma() -> None:
    # λk = 0.5; the only mass is p = 0.5 on (3, 4), at distance 1 from agent 0 and 2 from agent 1.
    config = cfg(n_agents=2, k=500.0)
    p = np.zeros((7, 7))
    p[3, 4] = 0.5
    state = make_world(config, 7, agents=[(3, 3), (3, 6)], targets=[(0, 0)], p=p)
    res = step(config, state, act(STAY, STAY), np.random.default_rng(0))
    f0, f1 = 0.5 * G1, 0.5 * G4
    removed = 0.5 * (1 - (1 - f0) * (1 - f1))
    credit = np.array([removed * f0 / (f0 + f1), removed * f1 / (f0 + f1)])
    np.testing.assert_allclose(state.p[0, 3 + state.halo, 4 + state.halo], 0.5 - removed, rtol=1e-6)
    np.testing.assert_allclose(res.info_collected[0], credit, rtol=1e-6)
    np.testing.assert_allclose(res.reward[0], -0.05 + 50.0 * credit, rtol=1e-6)


def _comm_world(communication: bool, n_agents: int = 2):
    """Agents in a row two cells apart near the top; planted values far outside every footprint and Φ."""
    config = cfg(world_size=(14, 14), n_agents=n_agents, communication=communication, explicit_area=5)
    p, u = np.zeros((14, 14)), np.zeros((14, 14))
    p[10, 10], p[12, 3], u[8, 12] = 0.125, 0.25, 0.0625
    agents = [(2, 2 + 2 * i) for i in range(n_agents)]
    state = make_world(config, 14, agents=agents, targets=[(13, 13)], p=p, u=u)
    h = state.halo
    state.belief[0, :, 0, 10 + h, 10 + h] = 0.5  # only agent 0 has seen (10, 10)
    state.belief[0, 0, 0, 10 + h, 10 + h] = 0.125
    state.belief[0, 0, 0, 12 + h, 3 + h] = 0.5  # everyone but agent 0 has seen (12, 3)
    state.belief[0, 0, 1, 8 + h, 12 + h] = 0.5  # likewise for u at (8, 12)
    # The state tracks where each belief may differ from the prior (`belief_box`, engine bookkeeping);
    # after editing beliefs by hand, the whole map is the honest box.
    state.belief_box[0] = (0, state.p.shape[1] - 1, 0, state.p.shape[2] - 1)
    return config, state


def test_communication_merges_by_elementwise_min() -> None:
    config, state = _comm_world(True)
    before = state.belief.copy()
    res = step(config, state, act(STAY, STAY), np.random.default_rng(0))
    np.testing.assert_array_equal(state.belief[0, 0], np.minimum(before[0, 0], before[0, 1]))
    np.testing.assert_array_equal(state.belief[0, 1], state.belief[0, 0])
    # ΔM (eq. 15-16): agent 0 gains 0.5 - 0.25 on p and 0.5 - 0.0625 on u, agent 1 gains 0.5 - 0.125 on p.
    np.testing.assert_array_equal(res.comm_gain[0], [0.25 + 0.4375, 0.375])
    np.testing.assert_allclose(res.reward[0], [-0.05 + 10 * 0.6875, -0.05 + 10 * 0.375], rtol=1e-6)
    assert res.comm_pairs[0] == 1 and state.ep_comm_pairs[0] == 1


def test_communication_does_not_relay_within_a_step() -> None:
    config, state = _comm_world(True, n_agents=3)  # 0-1 and 1-2 are neighbours, 0-2 are not
    h = state.halo
    res = step(config, state, act(STAY, STAY, STAY), np.random.default_rng(0))
    assert res.comm_pairs[0] == 2
    np.testing.assert_array_equal(state.belief[0, :, 0, 10 + h, 10 + h], [0.125, 0.125, 0.5])
    # Agent 0 still learns (12, 3) and u(8, 12) from agent 1; agent 2 gains nothing (agent 1's old map).
    np.testing.assert_array_equal(res.comm_gain[0], [0.6875, 0.375, 0.0])


def test_communication_off_counts_pairs_without_merging() -> None:
    config, state = _comm_world(False)
    before = state.belief.copy()
    res = step(config, state, act(STAY, STAY), np.random.default_rng(0))
    np.testing.assert_array_equal(state.belief, before)
    assert (res.comm_gain == 0).all() and res.comm_pairs[0] == 1 and state.ep_comm_pairs[0] == 1
    assert (res.reward[0] == np.float32(-0.05)).all()


def test_truncation_at_max_steps() -> None:
    config = cfg(max_steps=3)
    state = make_world(config, 7, agents=[(0, 0)], targets=[(6, 6)])
    flags = [step(config, state, act(STAY), np.random.default_rng(s)) for s in range(3)]
    assert [bool(r.truncated[0]) for r in flags] == [False, False, True]
    assert not any(bool(r.terminated[0]) for r in flags)


def test_draws_helper_matches_step_order() -> None:
    # The seed-picking above relies on priority being drawn before detect; check one draw is consumed each.
    pr, d = draws(7, 2, 1)
    rng = np.random.default_rng(7)
    assert rng.random() == pr[0] and rng.random() == pr[1] and rng.random() == d[0]


def test_observation_of_a_hand_built_world() -> None:
    config = cfg(n_agents=2, n_targets=(1, 2))  # fov 11: window offsets -5..5, centre (5, 5)
    state = make_world(config, 7, agents=[(0, 1), (2, 3)], targets=[(1, 1), (6, 6)], obstacles=((4, 4),))
    h = state.halo
    state.target_found[0, 0], state.found_grid[0, 1 + h, 1 + h], state.n_found[0] = True, True, 1
    state.obs_scale[0] = (2.0, 4.0)
    state.belief[0, 0, 0, 1 + h, 2 + h] = 0.25
    state.belief[0, 0, 1, 0 + h, 1 + h] = 0.125
    maps, vector = observe(config, state)
    me = maps[0, 0]
    assert me[0].sum() == 1 and me[0, 7, 7] == 1  # agent 1 two rows down, two cols right; not itself
    expected_blocked = np.ones((11, 11))
    expected_blocked[5:, 4:] = 0  # world rows 0..5, cols 0..6 are free; above and left is outside
    expected_blocked[9, 8] = 1  # the obstacle at (4, 4)
    np.testing.assert_array_equal(me[1], expected_blocked)
    assert me[2].sum() == 1 and me[2, 6, 5] == 1  # the found target at (1, 1)
    assert me[3, 6, 6] == 0.5 and me[4, 5, 5] == 0.5  # belief × obs_scale
    assert me[3].sum() == 0.5 and me[4].sum() == 0.5  # empty maps elsewhere
    assert maps[0, 1, 0].sum() == 1 and maps[0, 1, 0, 3, 3] == 1
    assert maps[0, 1, 1, 7, 6] == 1  # the obstacle at (4, 4) seen from (2, 3)
    np.testing.assert_allclose(vector[0], [[1 / 7, 0, 0.5], [3 / 7, 2 / 7, 0.5]], rtol=1e-6)
