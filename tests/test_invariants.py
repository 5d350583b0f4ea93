"""Properties of the engine over long random rollouts with auto reset, checked after every step."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from searchrl.world.config import WorldConfig
from searchrl.world.footprint import MOVES
from searchrl.world.reset import reset_worlds
from searchrl.world.scenario import Scenario
from searchrl.world.state import WorldState, allocate
from searchrl.world.step import StepResult, step
from tests.worldgen import count_pairs, scenarios, small_configs


def _check_maps(config: WorldConfig, before: WorldState, after: WorldState) -> None:
    # Sensing only removes information (eq. 1-2 with λkΓ <= 1), and a belief only ever holds an older (so
    # larger or equal) value of the true map: refresh copies it, the min-merge picks among such values.
    assert (after.p <= before.p).all() and (after.u <= before.u).all(), "a true map increased"
    assert (after.belief[:, :, 0] >= after.p[:, None]).all(), "a p belief is below the true map"
    assert (after.belief[:, :, 1] >= after.u[:, None]).all(), "a u belief is below the true map"
    if not config.communication:
        # Without communication a belief changes only inside the agent's explicit area Φ.
        h, r = after.halo, config.explicit_area // 2
        changed = after.belief != before.belief
        for k in range(after.n_worlds):
            for i in range(after.n_agents):
                row, col = after.pos[k, i] + h
                changed[k, i, :, row - r : row + r + 1, col - r : col + r + 1] = False
        assert not changed.any(), "a belief changed outside Φ with communication off"


def _check_agents(before: WorldState, after: WorldState, actions: np.ndarray, res: StepResult) -> None:
    h = after.halo
    proposed = before.pos + MOVES[actions]
    stay = actions == 0
    assert not res.collided[stay].any(), "a staying agent collided"
    moved = ~stay & ~res.collided
    np.testing.assert_array_equal(after.pos[moved], proposed[moved], err_msg="an unblocked move went elsewhere")
    np.testing.assert_array_equal(after.pos[~moved], before.pos[~moved], err_msg="a blocked/staying agent moved")
    for k in range(after.n_worlds):
        rows, cols = after.pos[k, :, 0], after.pos[k, :, 1]
        assert ((rows >= 0) & (rows < after.size[k]) & (cols >= 0) & (cols < after.size[k])).all()
        assert not after.blocked[k, rows + h, cols + h].any(), "an agent stands on a blocked cell"
        assert len({(int(r), int(c)) for r, c in zip(rows, cols, strict=True)}) == after.n_agents, "shared cell"
        np.testing.assert_array_equal(after.occupant[k, rows + h, cols + h], np.arange(after.n_agents))
        assert (after.occupant[k] >= 0).sum() == after.n_agents, "stale occupant entries"
    np.testing.assert_array_equal(after.ep_collisions - before.ep_collisions, res.collided.sum(axis=1))


def _check_targets(before: WorldState, after: WorldState, res: StepResult) -> None:
    assert (after.target_found | ~before.target_found).all(), "a found target became unfound"
    assert not (after.target_found & ~after.target_valid).any(), "an empty target slot was found"
    assert (res.targets_found >= 0).all()
    np.testing.assert_array_equal(after.n_found - before.n_found, res.targets_found.sum(axis=1))
    np.testing.assert_array_equal(after.n_found, after.target_found.sum(axis=1))
    h = after.halo
    for k in range(after.n_worlds):
        grid = np.zeros_like(after.found_grid[k])
        tp = after.target_pos[k, after.target_found[k]]
        grid[tp[:, 0] + h, tp[:, 1] + h] = True
        np.testing.assert_array_equal(after.found_grid[k], grid, err_msg="found_grid != found targets")


def _check_accounting(config: WorldConfig, before: WorldState, after: WorldState, res: StepResult) -> None:
    # Γ-weighted split: the agents' credits add up to what the true maps lost (float64 of float32 maps).
    lost = (before.p.astype(np.float64).sum(axis=(1, 2)) + before.u.astype(np.float64).sum(axis=(1, 2))) - (
        after.p.astype(np.float64).sum(axis=(1, 2)) + after.u.astype(np.float64).sum(axis=(1, 2))
    )
    assert (res.info_collected >= 0).all()
    np.testing.assert_allclose(res.info_collected.sum(axis=1), lost, rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(after.ep_info - before.ep_info, lost, rtol=1e-7, atol=1e-10)
    # F counts neighbour pairs whether or not communication is on; only a merge yields ΔM.
    pairs = [count_pairs(after.pos[k], config.comm_range // 2) for k in range(after.n_worlds)]
    np.testing.assert_array_equal(res.comm_pairs, pairs)
    np.testing.assert_array_equal(after.ep_comm_pairs - before.ep_comm_pairs, pairs)
    assert (res.comm_gain >= 0).all()
    if not config.communication:
        assert (res.comm_gain == 0).all(), "comm_gain with communication off"
    # Table 1 with eq. 5 and eq. 17, rebuilt from the other fields of the result.
    want = (
        config.step_reward
        + config.collision_reward * res.collided
        + config.target_reward * res.targets_found
        + (config.xi / config.lam) * res.info_collected  # eq. 5
        + (config.tau / config.lam) * res.comm_gain
    )
    np.testing.assert_allclose(res.reward, want, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(after.ep_return - before.ep_return, want.sum(axis=1), rtol=1e-5, atol=1e-5)


def _check_time(config: WorldConfig, before: WorldState, after: WorldState, res: StepResult) -> None:
    np.testing.assert_array_equal(after.t, before.t + 1)
    np.testing.assert_array_equal(res.terminated, after.n_found == after.n_targets)
    np.testing.assert_array_equal(res.truncated, (after.t >= config.max_steps) & ~res.terminated)
    assert not (res.terminated & res.truncated).any()
    assert (after.t <= config.max_steps).all(), "an episode outlived max_steps"


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    config=small_configs(max_steps=(2, 10)),
    scenario=scenarios(),
    n_worlds=st.integers(1, 4),
    seed=st.integers(0, 2**32),
)
def test_rollout_invariants(config: WorldConfig, scenario: Scenario, n_worlds: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    state = allocate(config, n_worlds)
    reset_worlds(config, state, np.ones(n_worlds, bool), rng, scenario)
    episodes_ended = 0
    for _ in range(40):
        before = state.copy()
        actions = rng.integers(0, config.n_actions, (n_worlds, config.n_agents))
        res = step(config, state, actions, rng)
        _check_maps(config, before, state)
        _check_agents(before, state, actions, res)
        _check_targets(before, state, res)
        _check_accounting(config, before, state, res)
        _check_time(config, before, state, res)
        done = res.terminated | res.truncated
        episodes_ended += int(done.sum())
        reset_worlds(config, state, done, rng, scenario)
        assert (state.t[done] == 0).all() and (state.n_found[done] == 0).all()
    # max_steps <= 10 over 40 steps: every world must have ended at least 4 episodes.
    assert episodes_ended >= 4 * n_worlds
