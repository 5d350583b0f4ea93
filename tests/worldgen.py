"""Shared test helpers: random small configurations (hypothesis) and exact/approximate state comparison."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from searchrl.world.config import WorldConfig
from searchrl.world.scenario import PAPER, IidObstacles, Scenario
from searchrl.world.state import WorldState
from searchrl.world.truth import OffPriorTargets

# Discrete state (positions, occupancy, targets, counters) must be bit-exact between engine and oracle.
DISCRETE_FIELDS = (
    "size", "t", "pos", "occupant", "blocked", "target_pos", "target_valid", "target_found", "found_grid",
    "n_targets", "n_found", "ep_comm_pairs", "ep_collisions", "belief_time", "swept", "ep_stale",
)  # fmt: skip
# Float state: SPEC fixes the order of the products, but sums over cells and agents may be taken in any order,
# so floats are compared to float32 rounding (rtol 1e-5) rather than bit for bit.
FLOAT_FIELDS = ("p", "u", "belief", "belief_seen", "obs_scale", "ep_return", "ep_info")
RTOL, ATOL = 1e-5, 1e-7


@st.composite
def small_configs(draw: st.DrawFn, max_steps: tuple[int, int] = (3, 30)) -> WorldConfig:
    """Small worlds, possibly of several sizes in one batch, with every switch of the agent model."""
    lo = draw(st.integers(6, 12))
    hi = draw(st.integers(lo, 14))
    fov, phi = draw(st.sampled_from([(11, 5), (11, 11), (7, 3), (7, 5)]))
    t_hi = draw(st.integers(1, 4))
    # λk = 1 (the Bayesian update), a partial one, or k = n and 40·n (k related to each world's side)
    sensings = [{"k": 1000.0}, {"k": 500.0}, {"k": 0.0, "k_per_n": 1.0}, {"k": 0.0, "k_per_n": 40.0}]
    sensing = draw(st.sampled_from(sensings))
    age = draw(st.sampled_from([0.0, 0.0, 2.0])) if sensing == {"k": 1000.0} else 0.0  # age needs λk = 1
    return WorldConfig(
        world_size=(lo, hi),
        n_distributions=(1, 3),
        n_targets=(draw(st.integers(1, t_hi)), t_hi),
        n_agents=draw(st.integers(1, 6)),
        **sensing,
        explicit_area=phi,
        fov=fov,
        communication=draw(st.booleans()),
        comm_range=draw(st.sampled_from([3, 5])),
        diagonal=draw(st.booleans()),
        max_steps=draw(st.integers(*max_steps)),
        belief_age=age,
        belief_age_channel=age > 0 and draw(st.booleans()),
        belief_seen=age > 0 and draw(st.booleans()),
    )


def scenarios() -> st.SearchStrategy[Scenario]:
    """The paper's scenario, iid obstacles, targets off the prior, or both."""
    return st.sampled_from([PAPER, Scenario(IidObstacles(0.1)), Scenario(targets=OffPriorTargets(0.5)),
                            Scenario(IidObstacles(0.1), OffPriorTargets(1.0))])  # fmt: skip


def assert_states_match(got: WorldState, want: WorldState, where: str = "") -> None:
    """Engine state `got` against oracle state `want`."""
    assert got.halo == want.halo
    for name in DISCRETE_FIELDS:
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=f"{name} {where}")
    for name in FLOAT_FIELDS:
        np.testing.assert_allclose(
            getattr(got, name), getattr(want, name), rtol=RTOL, atol=ATOL, err_msg=f"{name} {where}"
        )


def count_pairs(pos: np.ndarray, r_c: int) -> int:
    """Unordered agent pairs of one world within Chebyshev distance r_c; pos (N, 2)."""
    d = np.abs(pos[:, None, :] - pos[None, :, :]).max(axis=2)
    return int(((d <= r_c).sum() - len(pos)) // 2)
