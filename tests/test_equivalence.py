"""Engine == oracle on random small scenarios: the engine's `step` and `observe` against searchrl/world/oracle.py.

Discrete results and state are compared bit for bit; floats to float32 rounding (see worldgen.RTOL), since
the spec leaves the order of sums over cells and agents free.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from searchrl.world.config import WorldConfig
from searchrl.world.observe import observe
from searchrl.world.oracle import oracle_observe, oracle_step
from searchrl.world.reset import reset_worlds
from searchrl.world.scenario import PAPER, IidObstacles, Scenario
from searchrl.world.state import allocate
from searchrl.world.step import step
from tests.worldgen import ATOL, RTOL, assert_states_match, scenarios, small_configs

EXACT_RESULTS = {
    "terminated": ((-1,), np.bool_),
    "truncated": ((-1,), np.bool_),
    "collided": ((-1, -1), np.bool_),
    "targets_found": ((-1, -1), np.int64),
    "comm_pairs": ((-1,), np.int64),
}
FLOAT_RESULTS = {
    "reward": ((-1, -1), np.float32),
    "info_collected": ((-1, -1), np.float64),
    "comm_gain": ((-1, -1), np.float64),
}
SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _check_result(got: object, want: object, shape_kn: tuple[int, int], where: str) -> None:
    for name, (dims, dtype) in {**EXACT_RESULTS, **FLOAT_RESULTS}.items():
        g, w = np.asarray(getattr(got, name)), getattr(want, name)
        expected_shape = shape_kn[: len(dims)]
        assert g.shape == expected_shape, f"{name} shape {g.shape} != {expected_shape} {where}"
        assert g.dtype == dtype, f"{name} dtype {g.dtype} != {np.dtype(dtype)} {where}"
        if name in EXACT_RESULTS:
            np.testing.assert_array_equal(g, w, err_msg=f"{name} {where}")
        else:
            np.testing.assert_allclose(g, w, rtol=RTOL, atol=ATOL, err_msg=f"{name} {where}")


def _check_observation(config: WorldConfig, state: object, ref: object, where: str) -> None:
    maps, vector = observe(config, state)
    want_maps, want_vector = oracle_observe(config, ref)
    assert maps.shape == want_maps.shape and maps.dtype == np.float32, f"maps {maps.shape} {maps.dtype}"
    assert vector.shape == want_vector.shape and vector.dtype == np.float32, f"vector {vector.shape}"
    # Channels 0-2 are indicators: exact. Channels 3-4 and the vector are products/ratios: float32 rounding.
    np.testing.assert_array_equal(maps[:, :, :3], want_maps[:, :, :3], err_msg=f"obs channels 0-2 {where}")
    np.testing.assert_allclose(maps[:, :, 3:], want_maps[:, :, 3:], rtol=RTOL, atol=ATOL, err_msg=where)
    np.testing.assert_allclose(vector, want_vector, rtol=RTOL, atol=ATOL, err_msg=f"vector {where}")


def _run_both(config: WorldConfig, n_worlds: int, seed: int, n_steps: int, move_bias: float,
              scenario: Scenario = PAPER) -> None:  # fmt: skip
    """Reset, then step engine and oracle side by side with the same actions and equally seeded rngs,
    resetting finished worlds on both sides (the spec does not define a step of a finished world)."""
    state = allocate(config, n_worlds)
    reset_worlds(config, state, np.ones(n_worlds, bool), np.random.default_rng(seed), scenario)
    ref = state.copy()
    rng_engine, rng_oracle = np.random.default_rng(seed + 1), np.random.default_rng(seed + 1)
    action_rng = np.random.default_rng(seed + 2)
    shape_kn = (n_worlds, config.n_agents)
    _check_observation(config, state, ref, "after reset")
    for s in range(n_steps):
        # Mostly moves (move_bias) so collisions, contests and swaps happen often in small worlds.
        moves = action_rng.integers(1, config.n_actions, shape_kn)
        actions = np.where(action_rng.random(shape_kn) < move_bias, moves, 0)
        where = f"at step {s + 1}, actions={actions.tolist()}"
        got = step(config, state, actions.copy(), rng_engine)
        want = oracle_step(config, ref, actions.copy(), rng_oracle)
        _check_result(got, want, shape_kn, where)
        assert_states_match(state, ref, where)
        # Same draws in the same order: both generators must have advanced identically.
        assert rng_engine.bit_generator.state == rng_oracle.bit_generator.state, f"rng out of step {where}"
        _check_observation(config, state, ref, where)
        done = want.terminated | want.truncated
        if done.any():
            reset_worlds(config, state, done, rng_engine, scenario)
            reset_worlds(config, ref, done, rng_oracle, scenario)
            _check_observation(config, state, ref, f"after auto reset {where}")


@SETTINGS
@given(
    config=small_configs(),
    scenario=scenarios(),
    n_worlds=st.integers(1, 3),
    seed=st.integers(0, 2**32),
    n_steps=st.integers(1, 20),
    move_bias=st.sampled_from([0.5, 0.9]),
)
def test_engine_matches_oracle(config: WorldConfig, scenario: Scenario, n_worlds: int, seed: int, n_steps: int,
                               move_bias: float) -> None:  # fmt: skip
    _run_both(config, n_worlds, seed, n_steps, move_bias, scenario)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    n_agents=st.integers(4, 8),
    communication=st.booleans(),
    diagonal=st.booleans(),
    seed=st.integers(0, 2**32),
)
def test_engine_matches_oracle_crowded(n_agents: int, communication: bool, diagonal: bool, seed: int) -> None:
    """A 5×5 or 6×6 world packed with agents: contests for one cell, chains and swaps on most steps."""
    config = WorldConfig(
        world_size=(5, 6),
        n_distributions=(1, 2),
        n_targets=(1, 3),
        n_agents=n_agents,
        explicit_area=5,
        fov=7,
        communication=communication,
        diagonal=diagonal,
        max_steps=12,
    )
    _run_both(config, 2, seed, 12, 1.0)


@pytest.mark.slow
@pytest.mark.parametrize("explicit_area", [5, 11])
@pytest.mark.parametrize("communication", [False, True])
@pytest.mark.parametrize("diagonal", [False, True])
@pytest.mark.parametrize("obstacle_density", [0.0, 0.1])
def test_engine_matches_oracle_at_training_size(explicit_area, communication, diagonal, obstacle_density) -> None:
    """Paper-sized worlds (n 20-40, N = 8, Table 2 target counts) for 120 steps: every model setting."""
    config = WorldConfig(
        world_size=(20, 40),
        n_targets=(4, 8),
        explicit_area=explicit_area,
        communication=communication,
        diagonal=diagonal,
    )
    _run_both(config, 2, 7, 120, 0.9, Scenario(IidObstacles(obstacle_density)))
