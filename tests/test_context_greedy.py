"""Context-greedy: target-greedy that walks to the best pooled bin of its own belief when that beats its view."""

from __future__ import annotations

import numpy as np
import pytest

from searchrl.controllers.context_greedy import ContextGreedy
from searchrl.controllers.greedy import FootprintGreedy
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import MOVES
from searchrl.world.observe import observe
from searchrl.world.reset import reset_worlds
from searchrl.world.state import WorldState, allocate
from searchrl.world.step import step
from tests.handmade import make_world

N_, E, S, W = 1, 2, 3, 4
TARGET = dict(horizon=3, w_p=0.0, w_u=0.0, w_t=1.0)  # target-greedy's scoring


def _world(n_agents: int = 1, side: int = 64, diagonal: bool = False) -> tuple[WorldConfig, WorldState]:
    """A side × side world with p = u = 0 everywhere (the caller adds prior mass), agents from the centre row."""
    config = WorldConfig(world_size=(side, side), n_agents=n_agents, n_targets=(1, 1), diagonal=diagonal)
    agents = [(side // 2, side // 2 - 3 * i) for i in range(n_agents)]
    return config, make_world(config, side, agents, targets=[(0, 0)])


def _mass(state: WorldState, rows: slice, cols: slice, value: float = 1.0) -> None:
    """Target probability `value`, nothing collected, on the block rows × cols of every agent's belief."""
    h = state.halo
    state.belief[0, :, 0, rows.start + h : rows.stop + h, cols.start + h : cols.stop + h] = value


def _act(ctrl: FootprintGreedy, state: WorldState) -> np.ndarray:
    return ctrl.act(state, *observe(ctrl.config, state))[0]


@pytest.mark.parametrize(
    "rows, cols, action",
    [(slice(28, 36), slice(56, 64), E), (slice(28, 36), slice(0, 8), W), (slice(0, 8), slice(28, 36), N_)],
)
def test_context_greedy_walks_to_mass_beyond_its_view(rows, cols, action):
    config, state = _world()
    _mass(state, rows, cols)  # 24+ cells away from the agent at (32, 32): far outside its 11×11 view
    ctrl = ContextGreedy(config, context=8, **TARGET)
    assert _act(ctrl, state)[0] == action
    assert _act(ctrl, state)[0] == action  # the aim is kept


def test_context_greedy_takes_greedys_move_when_its_view_is_richer():
    config, state = _world()
    _mass(state, slice(32, 33), slice(35, 36))  # one rich cell 3 east, in view
    _mass(state, slice(28, 36), slice(56, 64), 0.01)  # faint mass far east, outside it
    greedy, context = FootprintGreedy(config, **TARGET), ContextGreedy(config, context=8, **TARGET)
    assert _act(context, state)[0] == _act(greedy, state)[0] == E


def test_margin_decides_when_a_far_bin_is_worth_leaving_for():
    config, state = _world()
    _mass(state, slice(32, 33), slice(27, 28), 0.05)  # a faint cell 5 west, in view
    _mass(state, slice(0, 8), slice(28, 36))  # a rich block far north
    assert _act(ContextGreedy(config, context=8, margin=1.0, **TARGET), state)[0] == N_
    assert _act(ContextGreedy(config, context=8, margin=1e6, **TARGET), state)[0] == W


def test_context_greedy_moves_diagonally_in_the_diagonal_model():
    config, state = _world(diagonal=True)
    _mass(state, slice(56, 64), slice(56, 64))  # south-east
    action = _act(ContextGreedy(config, context=8, **TARGET), state)[0]
    assert tuple(MOVES[action]) == (1, 1)


def test_with_an_unreachable_margin_it_is_target_greedy_on_random_worlds():
    config = WorldConfig(world_size=(40, 40), n_agents=4)
    state = allocate(config, 3)
    reset_worlds(config, state, np.ones(3, bool), np.random.default_rng(0))
    greedy, context = FootprintGreedy(config, seed=5, **TARGET), ContextGreedy(config, seed=5, margin=1e9, **TARGET)
    rng = np.random.default_rng(1)
    for _ in range(30):
        maps, vector = observe(config, state)
        actions = greedy.act(state, maps, vector)
        np.testing.assert_array_equal(context.act(state, maps, vector), actions)
        step(config, state, actions, rng)


@pytest.mark.parametrize("settings, named", [({"margin": 0.5}, "margin=0.5"), ({"context": 1}, "context=1")])
def test_bad_settings_are_named(settings, named):
    config, _ = _world()
    with pytest.raises(ValueError, match=named):
        ContextGreedy(config, **settings)


def test_divide_sends_teammates_that_see_each_other_to_different_ground():
    """Two agents 3 apart: without `divide` both head for the richer block east; with it the western one takes
    the block west, to which it stands nearer than its teammate."""
    config, state = _world(n_agents=2)  # agent 0 at (32, 32), agent 1 at (32, 29)
    _mass(state, slice(28, 36), slice(56, 64))  # east, richer
    _mass(state, slice(28, 36), slice(0, 8), 0.9)  # west
    assert _act(ContextGreedy(config, context=8, **TARGET), state).tolist() == [E, E]
    assert _act(ContextGreedy(config, context=8, divide=True, **TARGET), state).tolist() == [E, W]
