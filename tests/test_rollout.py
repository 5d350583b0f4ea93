"""Rollout-greedy (searchrl/controllers/rollout.py): one step of policy improvement over footprint-greedy."""

from __future__ import annotations

import numpy as np
import pytest

from searchrl.controllers.greedy import FootprintGreedy
from searchrl.controllers.rollout import GreedyRollout, _information_map
from searchrl.world.config import WorldConfig
from searchrl.world.observe import observe
from tests.handmade import make_world

E, W = 2, 4
CONFIG = WorldConfig(world_size=(30, 30), n_agents=1, n_targets=(1, 1))


def _world(positions: list[tuple[int, int]]):
    """A 30×30 world with zero beliefs (the test adds information), agents at `positions`, one target in a corner."""
    return make_world(CONFIG if len(positions) == 1 else WorldConfig(world_size=(30, 30), n_agents=len(positions),
                      n_targets=(1, 1)), 30, positions, targets=[(0, 0)])  # fmt: skip


def _act(ctrl, state) -> np.ndarray:
    return ctrl.act(state, *observe(ctrl.config, state))[0]


def _lane_beyond_the_view(state) -> None:
    """One cell of 1.0 three cells west of the agent at (15, 15); east, 0.9 four cells away, in view, and the same
    on every cell from there to the east edge, beyond the 11×11 view."""
    h = state.halo
    state.belief[0, 0, 0, 15 + h, 12 + h] = 1.0  # p; u stays 0, so p̂·(1 − û) = p̂
    state.belief[0, 0, 0, 15 + h, 19 + h : 30 + h] = 0.9


def test_rollout_follows_the_mass_beyond_the_view_that_greedy_leaves():
    state = _world([(15, 15)])
    _lane_beyond_the_view(state)
    assert _act(FootprintGreedy(CONFIG, horizon=3, w_p=0, w_u=0, w_t=1), state)[0] == W  # the nearer cell
    assert _act(GreedyRollout(CONFIG, rollout=32, horizon=3, w_p=0, w_u=0, w_t=1), state)[0] == E
    # imagined for two steps, the east lane is still out of reach: the rollout agrees with greedy
    assert _act(GreedyRollout(CONFIG, rollout=2, horizon=3, w_p=0, w_u=0, w_t=1), state)[0] == W


def test_a_one_step_rollout_is_greedy_with_horizon_one():
    """Imagined for one step, a move is worth what its footprint senses there: greedy's score with horizon 1 (the
    footprint one move away lies inside the view), on random beliefs of a team, fallbacks included."""
    config = WorldConfig(world_size=(30, 30), n_agents=4, n_targets=(1, 1))
    rng = np.random.default_rng(3)
    for _ in range(5):
        state = _world([tuple(x) for x in rng.choice(30, size=(4, 2), replace=False)])
        h = state.halo
        state.belief[0, :, :, h : 30 + h, h : 30 + h] = rng.random((4, 2, 30, 30)) * (rng.random((30, 30)) < 0.05)
        greedy = FootprintGreedy(config, horizon=1, w_t=1.0, reach=2.0, seed=5)
        rollout = GreedyRollout(config, rollout=1, horizon=1, w_t=1.0, reach=2.0, seed=5)
        np.testing.assert_array_equal(_act(rollout, state), _act(greedy, state))


def test_the_information_map_reads_the_belief_as_greedy_with_seen_and_age_does():
    """m = reach · p̂·(1 − û), p̂ and û scaled by what the neighbours seen sensed and by exp(−rate·(t − t₀)), t₀ the
    step each cell's truth was last seen (greedy's `seen` and `age`, searchrl/world/seen.py)."""
    config = WorldConfig(world_size=(30, 30), n_agents=4, n_targets=(1, 1))
    rng = np.random.default_rng(4)
    state = _world([(5, 5), (5, 8), (20, 20), (25, 3)])
    h = state.halo
    state.belief[0, :, :, h : 30 + h, h : 30 + h] = rng.random((4, 2, 30, 30))
    state.t[:] = 50
    rollout = GreedyRollout(config, w_p=0.0, w_u=0.0, w_t=1.0, reach=2.0, seen=True, age=0.5)
    memory = rollout.remember(state)
    m = np.zeros(state.blocked.shape[1:])
    _information_map(state.arrays(), rollout._params, memory, 0, 0, m)
    fresh = np.exp(-memory.rates[0] * (50 - memory.known[0, 0]))
    scale = memory.seen[0, 0] * fresh
    p, u = state.belief[0, 0, 0] * state.obs_scale[0, 0] * scale, state.belief[0, 0, 1] * state.obs_scale[0, 1] * scale
    np.testing.assert_allclose(m, memory.reach[0] * p * np.clip(1 - u, 0, None), rtol=1e-6)
    assert (fresh < 0.9).any() and (fresh == 1).any() and (memory.seen[0, 0] < 1).any()  # each factor is at work


MATES = [(18, {"mates": 0}, E), (18, {"mates": 1}, W), (24, {"mates": 1}, E),
         (24, {"mates": 1, "mates_anywhere": True}, W)]  # fmt: skip


@pytest.mark.parametrize("mate_col, kwargs, action", MATES)
def test_mates_leaves_to_a_teammate_the_mass_it_reaches_first(mate_col, kwargs, action):
    """1.0 six cells east of agent 0 and 0.6 six cells west; a teammate three cells east of agent 0 (in view) or
    nine (out of view, three beyond the east cell). Imagined alone, agent 0 heads east for the larger mass;
    imagining the teammate's greedy beside it, it sees the teammate sense the east cell first and heads west,
    but only for a teammate in view unless `mates_anywhere`."""
    config = WorldConfig(world_size=(30, 30), n_agents=2, n_targets=(1, 1))
    state = _world([(15, 15), (15, mate_col)])
    h = state.halo
    state.belief[0, :, 0, 15 + h, 21 + h] = 1.0
    state.belief[0, :, 0, 15 + h, 9 + h] = 0.6
    rollout = GreedyRollout(config, rollout=32, horizon=3, w_p=0, w_u=0, w_t=1, **kwargs)
    assert _act(rollout, state)[0] == action


def test_the_imagined_sensing_is_undone():
    state = _world([(15, 15)])
    _lane_beyond_the_view(state)
    rollout = GreedyRollout(CONFIG, rollout=64, w_t=1.0)
    _act(rollout, state)  # its scratch map is undone after every candidate move: the agent's information again
    information = np.zeros_like(rollout._map)
    _information_map(state.arrays(), rollout._params, rollout.remember(state), 0, 0, information)
    assert information.max() > 0
    np.testing.assert_array_equal(rollout._map, information)


BAD = [({"rollout": 0}, "rollout"), ({"rollout": 257}, "rollout"), ({"rollout_discount": 0.0}, "rollout_discount"),
       ({"rollout_discount": 1.5}, "rollout_discount"), ({"contested": 0.5}, "contested"), ({"age": 5.0}, "age"),
       ({"far": True}, "far"), ({"horizon": 0}, "horizon"), ({"mates": -1}, "mates"),
       ({"mates": 9}, "mates")]  # fmt: skip


@pytest.mark.parametrize("kwargs, name", BAD)
def test_bad_parameters_are_named(kwargs, name):
    with pytest.raises(ValueError, match=name):
        GreedyRollout(WorldConfig(), **kwargs)
