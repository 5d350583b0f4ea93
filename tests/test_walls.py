"""Wall-aware heuristics (searchrl/controllers/walls.py): shortest paths around walls, every free cell of a maze
reached eventually, and the rules' settings checked."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from searchrl.controllers.registry import HEURISTICS, make_controller
from searchrl.controllers.switch import sweep_footprints
from searchrl.controllers.walls import bfs
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.footprint import MOVES, SUPPORT_DC, SUPPORT_DR, SUPPORT_G
from searchrl.world.scenario import Scenario

MAZE = Scenario.from_dict({"obstacles": {"kind": "maze", "corridor": 1, "loops": 0.0}})


def test_bfs_finds_shortest_paths_around_a_wall():
    blocked = np.zeros((1, 7, 7), bool)
    blocked[0, 0, :] = blocked[0, -1, :] = blocked[0, :, 0] = blocked[0, :, -1] = True  # the halo
    blocked[0, 1:5, 3] = True  # a wall from the top, open at row 5
    dist, first = np.full((7, 7), -1, np.int32), np.zeros((7, 7), np.int64)
    queue = np.zeros((49, 2), np.int64)
    reached = bfs(blocked, 0, 1, 1, -1, 5, dist, first, queue)
    assert reached == 25 - 4
    assert dist[1, 5] == 4 + 4 + 4  # down to row 5, across, up: around the wall, not through it
    assert tuple(MOVES[first[1, 5]]) in {(1, 0), (0, 1)}  # south or east: both start a shortest path
    assert dist[1, 2] == 1 and dist[3, 3] == -1


@pytest.mark.parametrize("name", ["sweep", "path_greedy"])
def test_a_lone_agent_reaches_every_free_cell_of_a_maze(name):
    """Corridors one cell wide and no loops, so every dead end must be walked into. Sweep: every free cell ends at
    least half sensed (Π (1 − Γ) <= 0.5 over the agent's footprints). Path-greedy: no free cell keeps more of
    target-greedy's information than its walk's floor (a share of the prior's mean)."""
    config = WorldConfig(world_size=(15, 15), n_targets=(1, 1), n_distributions=(2, 2), n_agents=1, max_steps=4000)
    world = SearchWorld(config, 2, seed=3, scenario=MAZE, auto_reset=False)
    world.reset()  # a finished world keeps stepping (unreset): its agent's moves are what the test follows
    controller = make_controller(name, config, seed=0)
    controller.reset(world.state, np.ones(2, bool))
    state, h = world.state, world.state.halo
    left = np.ones(state.p.shape)
    maps, vector = world.observation
    for _ in range(1500):
        sweep_footprints(state.pos, h, left, SUPPORT_DR, SUPPORT_DC, SUPPORT_G)
        transition = world.step(controller.act(state, maps, vector))
        maps, vector = transition.maps, transition.vector
    free = ~state.blocked
    if name == "sweep":
        assert (left[free] <= 0.5).all(), f"{(left[free] > 0.5).sum()} free cells less than half sensed"
    else:
        p_hat = state.belief[:, 0, 0] * state.obs_scale[:, 0, None, None]
        u_hat = state.belief[:, 0, 1] * state.obs_scale[:, 1, None, None]
        info = np.where(free, p_hat * np.maximum(0.0, 1.0 - u_hat), 0.0)
        assert (info <= controller._floor[:, None, None] * (1 + 1e-6)).all()
        assert (left[free] <= 0.5).mean() > 0.5  # it walked the maze, not a corner of it


@pytest.mark.parametrize("name, settings, message", [
    ("path_greedy", {"radius": 0}, "radius=0 is not allowed: 1 <= radius <= 5 (half the view)"),
    ("path_greedy", {"radius": 6}, "radius=6 is not allowed: 1 <= radius <= 5 (half the view)"),
    ("path_greedy", {"worth": 0.0}, "worth=0.0 is not allowed: 0 < worth <= 1 (a share of the prior's mean)"),
    ("path_greedy", {"worth": 1.01}, "worth=1.01 is not allowed: 0 < worth <= 1 (a share of the prior's mean)"),
    ("sweep", {"spacing": -1}, "spacing=-1 is not allowed: 0 <= spacing <= 16 (cells)"),
    ("sweep", {"spacing": 17}, "spacing=17 is not allowed: 0 <= spacing <= 16 (cells)"),
])  # fmt: skip
def test_bad_settings_are_named(name, settings, message):
    with pytest.raises(ValueError) as refused:
        make_controller(name, WorldConfig(), settings=settings)
    assert str(refused.value) == message


@pytest.mark.parametrize("name, settings", [("path_greedy", {"radius": 1, "worth": 1.0}),
                                            ("path_greedy", {"radius": 5}), ("sweep", {"spacing": 0}),
                                            ("sweep", {"spacing": 16})])  # fmt: skip
def test_the_last_settings_allowed_make_a_rule(name, settings):
    make_controller(name, WorldConfig(), settings=settings)


WALLS = Scenario.from_dict({"obstacles": {"kind": "iid", "density": 0.2, "connected": True}})
# sha256 (first 16 hex) of the moves of 3 worlds x 6 agents over 60 steps among iid walls (walls.py as at 23e4ee9):
# the rules' python shells (scratch, team memory, floors, resets) as well as their kernels
RECORDED_MOVES = {"path_greedy": "568e230f767677fe", "sweep": "db07b09cdf0521af"}


def _moves(name: str, reset_first: bool, **kwargs) -> str:
    config = WorldConfig(world_size=(20, 24), n_agents=6, n_targets=(4, 6), n_distributions=(3, 5))
    world = SearchWorld(config, 3, seed=11, scenario=WALLS)
    world.reset()
    controller = make_controller(name, config, **kwargs)
    if reset_first:
        controller.reset(world.state, np.ones(3, bool))
    maps, vector = world.observation
    digest = hashlib.sha256()
    for _ in range(60):
        actions = controller.act(world.state, maps, vector)
        digest.update(np.ascontiguousarray(actions, np.int64).tobytes())
        transition = world.step(actions)
        maps, vector = transition.maps, transition.vector
        if transition.result.terminated.any() or transition.result.truncated.any():
            controller.reset(world.state, transition.result.terminated | transition.result.truncated)
    return digest.hexdigest()[:16]


@pytest.mark.parametrize("name", ["path_greedy", "sweep"])
def test_the_rules_make_their_recorded_moves_seeded_by_default_with_zero_and_without_a_first_reset(name):
    assert _moves(name, True, seed=0) == RECORDED_MOVES[name]
    rule = HEURISTICS[name].cls
    default, zero = rule(WorldConfig()), rule(WorldConfig(), seed=0)
    assert (default.rng.integers(0, 2**31, 8) == zero.rng.integers(0, 2**31, 8)).all()  # the default seed is 0
    assert _moves(name, False, seed=0) == RECORDED_MOVES[name]  # the first act resets what reset would


def test_rows_record_how_often_moves_are_blocked_and_agents_sweep_nothing_new():
    """In a maze: `blocked`, the share of a team's moves a wall or an agent stopped: a random walk runs into walls
    often, path_greedy moves along free paths and almost never. `stale`, the share of agent-steps whose footprint
    swept no free cell new to the team: geometric coverage stands at a wall (stale, never blocked: it does not try
    the move), sweep keeps finding new cells."""
    from searchrl.evaluate.grid import Cell
    from searchrl.evaluate.runner import run_cell

    config = WorldConfig(world_size=(20, 20), n_targets=(4, 4), n_distributions=(4, 4), n_agents=1)
    maze = Scenario.from_dict({"obstacles": {"kind": "maze", "corridor": 2, "loops": 0.1}})
    frames = {}
    for name in ("random", "path_greedy", "coverage", "sweep"):

        def factory(cfg, streams, name=name):
            return make_controller(name, cfg, seed=streams)

        frames[name] = run_cell(factory, config, Cell(20, 2, 4, 4), 0, 4, 1, 11, needs_observation=False, scenario=maze)
        assert frames[name]["blocked"].between(0, 1).all() and frames[name]["stale"].between(0, 1).all()
    blocked = {name: frame["blocked"].mean() for name, frame in frames.items()}
    assert blocked["random"] > 0.1 and blocked["path_greedy"] < blocked["random"] / 4, blocked
    assert frames["coverage"]["stale"].mean() > 0.8 and blocked["coverage"] < 0.05
    assert frames["sweep"]["stale"].mean() < 0.4


def test_a_step_is_stale_when_the_footprint_holds_nothing_new():
    """SPEC step 3, *Swept*: the first step senses new cells; standing still afterwards senses none; an agent
    whose footprint reaches one unswept free cell is not stale."""
    import numpy as np

    from searchrl.world.reset import reset_worlds
    from searchrl.world.state import allocate
    from searchrl.world.step import step

    config = WorldConfig(world_size=(12, 12), n_agents=1, n_targets=(1, 1), n_distributions=(1, 1))
    state = allocate(config, 1)
    reset_worlds(config, state, np.ones(1, bool), np.random.default_rng(0))
    rng = np.random.default_rng(1)
    stay = np.zeros((1, 1), np.int64)
    step(config, state, stay, rng)
    assert state.ep_stale[0] == 0 and state.swept[0].sum() > 0
    step(config, state, stay, rng)
    assert state.ep_stale[0] == 1
    row, col = state.pos[0, 0] + state.halo
    state.swept[0, row + 2, col] = False  # one cell of its footprint unswept again
    step(config, state, stay, rng)
    assert state.ep_stale[0] == 1 + (state.blocked[0, row + 2, col])


def test_path_greedy_looks_no_further_than_its_radius():
    """A little information 2 moves east and much 5 moves west: with radius 2 the west cell lies beyond every
    footprint path_greedy scores (a footprint at 2 moves reaches 4), so it goes east; one move more of search
    would see the west cell and turn there."""
    config = WorldConfig(world_size=(21, 21), n_targets=(1, 1), n_distributions=(2, 2), n_agents=1)
    world = SearchWorld(config, 1, seed=0)
    world.reset()
    state, h = world.state, world.state.halo
    r0 = c0 = 10
    state.pos[0, 0] = (r0, c0)
    state.occupant[0][state.occupant[0] >= 0] = -1
    state.occupant[0, r0 + h, c0 + h] = 0
    east, west = [int(np.flatnonzero((MOVES == m).all(axis=1))[0]) for m in ((0, 1), (0, -1))]
    for radius, expected in ((2, east), (3, west)):
        rule = make_controller("path_greedy", config, seed=0, settings={"radius": radius})
        rule.reset(state, np.ones(1, bool))
        state.belief[0, 0, :] = 0.0  # the agent believes in two cells only, with u = 0 (nothing ruled out)
        state.belief[0, 0, 0, r0 + h, c0 + 2 + h] = 0.2
        state.belief[0, 0, 0, r0 + h, c0 - 5 + h] = 20.0
        assert rule.act(state, *world.observation)[0, 0] == expected, radius


def test_path_greedy_takes_its_discount_and_seed():
    """Its discount reaches the kernel's settings (the default equals target-greedy's, so only another value shows
    it), and its seed its random fallback moves."""
    config = WorldConfig()
    assert make_controller("path_greedy", config, settings={"discount": 0.3})._params.discount == 0.3
    draws = [make_controller("path_greedy", config, seed=s).rng.integers(0, 1 << 30, 8) for s in (1, 1, 2)]
    assert (draws[0] == draws[1]).all() and (draws[0] != draws[2]).any()
