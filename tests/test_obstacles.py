"""Obstacle generators (searchrl/world/obstacles.py): every free cell reachable, room for agents and targets, no
agent or target on a wall, PRIMAL's density law, mazes and rooms as their laws say, and bad settings named."""

from __future__ import annotations

import re

import numpy as np
import pytest

from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.obstacles import IidObstacles, MazeObstacles, PrimalObstacles, RoomObstacles, largest_region
from searchrl.world.reset import reset_world
from searchrl.world.scenario import Scenario
from searchrl.world.state import allocate

CONNECTED = [IidObstacles(0.3, connected=True), PrimalObstacles(), MazeObstacles(), MazeObstacles(2, 0.0),
             RoomObstacles(), RoomObstacles(6, 1)]  # fmt: skip


def test_largest_region_keeps_the_largest_four_connected_free_region():
    free = np.array([[1, 1, 0, 1],
                     [0, 1, 0, 1],
                     [1, 0, 0, 1],
                     [1, 0, 1, 1]], bool)  # fmt: skip
    want = np.array([[0, 0, 0, 1], [0, 0, 0, 1], [0, 0, 0, 1], [0, 0, 1, 1]], bool)
    np.testing.assert_array_equal(largest_region(free), want)  # the diagonal does not connect (1,1)-(2,0)
    assert not largest_region(np.zeros((3, 3), bool)).any()


@pytest.mark.parametrize("generator", CONNECTED, ids=lambda g: g.label)
def test_every_free_cell_is_reachable_and_there_is_room(generator):
    for n in (20, 41, 80):
        for seed in range(8):
            walls = generator(n, 30, np.random.default_rng(seed))
            free = ~walls
            assert walls.shape == (n, n) and walls.dtype == bool and free.sum() >= 30
            np.testing.assert_array_equal(largest_region(free), free)
            np.testing.assert_array_equal(walls, generator(n, 30, np.random.default_rng(seed)))  # seeded


def test_iid_walls_without_connected_are_todays_draws_and_may_cut_regions_off():
    rng_a, rng_b = np.random.default_rng(3), np.random.default_rng(3)
    np.testing.assert_array_equal(IidObstacles(0.3)(30, 10, rng_a), rng_b.random((30, 30)) < 0.3)
    cut_off = [not np.array_equal(largest_region(~w), ~w)
               for w in (IidObstacles(0.3)(30, 10, np.random.default_rng(s)) for s in range(10))]  # fmt: skip
    assert any(cut_off)  # which is why `connected` exists


@pytest.mark.parametrize("generator", [*CONNECTED, IidObstacles(0.2)], ids=lambda g: g.label)
def test_no_agent_or_target_starts_on_a_wall(generator):
    config = WorldConfig(world_size=(40, 40), n_targets=(8, 8), n_distributions=(4, 4), n_agents=6)
    state = allocate(config, 1)
    h = state.halo
    for seed in range(10):
        reset_world(config, state, 0, np.random.default_rng(seed), Scenario(generator))
        blocked = state.blocked[0, h : h + 40, h : h + 40]
        targets, agents = state.target_pos[0, :8], state.pos[0]
        assert not blocked[targets[:, 0], targets[:, 1]].any() and not blocked[agents[:, 0], agents[:, 1]].any()
        p = state.p[0, h : h + 40, h : h + 40]
        assert (p[blocked] == 0).all() and np.isclose(p.sum(), 1.0, atol=1e-5)  # the prior renormalised


def test_primal_draws_its_density_from_the_triangular_law():
    for seed in range(20):  # one triangular(0, 0.33, 0.5) density, iid walls at it, the reachable region kept
        rng = np.random.default_rng(seed)
        density = rng.triangular(0.0, 0.33, 0.5)
        want = ~largest_region(~(rng.random((24, 24)) < density))
        np.testing.assert_array_equal(PrimalObstacles()(24, 10, np.random.default_rng(seed)), want)
    shares = [PrimalObstacles()(24, 10, np.random.default_rng(s)).mean() for s in range(300)]
    # mean density 0.277; above about 0.4 iid walls cut the free cells into pockets, which become walls
    assert 0.26 < np.mean(shares) < 0.45 and min(shares) < 0.08


def test_a_maze_has_corridors_of_its_width_and_loops_open_walls():
    tree = MazeObstacles(corridor=3, loops=0.0)(39, 10, np.random.default_rng(0))
    loopy = MazeObstacles(corridor=3, loops=0.5)(39, 10, np.random.default_rng(0))
    assert loopy.sum() < tree.sum()
    assert not tree[:3, :3].any() and tree[3, 3] and tree[7, 7]  # a lattice cell is free, a lattice corner a wall
    # a perfect maze is a tree of lattice cells: free cells = cells' area + one opening of `corridor` per edge
    side = 40 // 4
    assert (~tree).sum() == side * side * 9 + (side * side - 1) * 3


def test_rooms_are_split_by_walls_with_doors():
    walls = RoomObstacles(room_size=12, door=3)(80, 10, np.random.default_rng(1))
    assert 0.02 < walls.mean() < 0.2
    big = RoomObstacles(room_size=200, door=3)(80, 10, np.random.default_rng(1))
    assert not big.any()  # no region is large enough to divide


@pytest.mark.parametrize("values, message", [
    ({"kind": "maze", "corridor": 0}, "scenario.obstacles.corridor=0 is not allowed"),
    ({"kind": "maze", "loops": 2}, "scenario.obstacles.loops=2 is not allowed"),
    ({"kind": "rooms", "door": 20}, "scenario.obstacles.door=20 is not allowed"),
    ({"kind": "rooms", "room_size": 2}, "scenario.obstacles.room_size=2 is not allowed"),
    ({"kind": "iid", "density": 0.2, "connected": "yes"}, "scenario.obstacles.connected='yes' is not allowed"),
])  # fmt: skip
def test_bad_obstacle_settings_are_named(values, message):
    config = WorldConfig(world_size=(40, 40), n_targets=(8, 8), n_agents=4)
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(".", r"\.")):
        Scenario.from_dict({"obstacles": values}).check(config)


class _Lowest:
    """A generator stand-in whose `integers(low, high)` is always `low`: the recursive division made predictable."""

    def integers(self, low, high=None):
        return low


@pytest.mark.parametrize("door", [1, 3, 5])
def test_each_room_wall_has_a_door_exactly_door_cells_wide(door):
    """n = 12, room_size 12, every random choice its lowest: a horizontal wall at row 1 with its door at columns
    0..door-1, then in the lower region a vertical wall at column 1 from row 2 with its door at rows 2..door+1."""
    walls = RoomObstacles(room_size=12, door=door).draw(12, _Lowest())
    assert not walls[1, :door].any() and walls[1, door:].all()
    assert not walls[2 : 2 + door, 1].any() and walls[2 + door :, 1].all()
    assert walls.sum() == (12 - door) + (10 - door)  # nothing else: both halves are then too small to divide


@pytest.mark.parametrize("generator, what", [
    (PrimalObstacles(), "PRIMAL's walls"),
    (RoomObstacles(4, 1), "rooms of 4"),
    (MazeObstacles(9, 0.0), "scenario.obstacles.corridor=9"),
    (IidObstacles(0.5, connected=True), "scenario.obstacles.density=0.5 with connected=true"),
    (IidObstacles(0.5), "scenario.obstacles.density=0.5"),
])  # fmt: skip
def test_a_world_whose_walls_never_leave_room_is_refused_naming_the_generator(generator, what):
    """A 20x20 world holds 400 agents and targets only without a wall: after its 100 draws the generator says so."""
    message = f"{what} is not allowed here: 100 draws left fewer than 400 free cells (agents and targets) of 20x20"
    with pytest.raises(ConfigError, match=f"^{re.escape(message)}$"):
        generator(20, 400, np.random.default_rng(0))


def test_exactly_as_many_free_cells_as_agents_and_targets_is_room_enough():
    """A maze without loops frees the same cells in every draw: at n = 20, corridor 9, 2x2 squares of 81 cells and
    the 3 openings of 9 of its spanning tree, 351 cells. A team of 351 fits; of 352 it is refused."""
    maze = MazeObstacles(corridor=9, loops=0.0)
    assert (~maze(20, 351, np.random.default_rng(0))).sum() == 351
    with pytest.raises(ConfigError, match="fewer than 352 free cells"):
        maze(20, 352, np.random.default_rng(0))
