"""Obstacle generators, a scenario's `obstacles` part: `generator(n, room, rng) -> (n, n) bool` (True on walls) or
None, drawn after the prior; `room` is how many free cells the agents and targets need (distinct cells).

- `IidObstacles` (iid): each cell a wall with probability `density`; with `connected`, only the largest
  4-connected region of free cells stays free (every free cell reachable by the cardinal moves all models have).
- `PrimalObstacles` (primal): PRIMAL's training law (Sartoretti et al., RA-L 2019): a density drawn per map from
  triangular(0, 0.33, 0.5), iid walls at it, connected.
- `MazeObstacles` (maze): a perfect maze of corridors `corridor` cells wide carved by a randomised depth-first
  search, then a share `loops` of its remaining inner walls opened (cycles, as PRIMAL2's mazes have), connected.
- `RoomObstacles` (rooms): recursive division of the world by one-cell walls, each with a door `door` cells wide,
  until a region is below `room_size` on a side: rooms and corridors, connected by construction.

Every generator repeats its draw (at most 100 times) until `room` cells are free, and draws nothing at density 0
(iid), so the paper's worlds are drawn bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numba import njit

from searchrl.registry import Registry
from searchrl.world.config import ConfigError, WorldConfig, is_int, need
from searchrl.world.truth import finite

_MAX_OBSTACLE_DRAWS = 100


@njit(cache=True)
def largest_region(free: np.ndarray) -> np.ndarray:
    """(n, n) bool: the largest 4-connected region of `free` (n, n) bool (flood fill; the first found on ties)."""
    n_rows, n_cols = free.shape
    label = np.zeros((n_rows, n_cols), np.int32)
    stack = np.empty((n_rows * n_cols, 2), np.int64)
    best, best_size, current = 0, 0, 0
    for r0 in range(n_rows):
        for c0 in range(n_cols):
            if not free[r0, c0] or label[r0, c0] != 0:
                continue
            current += 1
            label[r0, c0] = current
            stack[0, 0], stack[0, 1] = r0, c0
            top, size = 1, 0
            while top > 0:
                top -= 1
                r, c = stack[top, 0], stack[top, 1]
                size += 1
                for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                    rr, cc = r + dr, c + dc
                    if 0 <= rr < n_rows and 0 <= cc < n_cols and free[rr, cc] and label[rr, cc] == 0:
                        label[rr, cc] = current
                        stack[top, 0], stack[top, 1] = rr, cc
                        top += 1
            if size > best_size:
                best, best_size = current, size
    return label == best if best > 0 else np.zeros((n_rows, n_cols), np.bool_)


def _until_room(draw, room: int, what: str, n: int) -> np.ndarray:
    """Repeat `draw()` (walls (n, n) bool) until `room` cells are free; ConfigError after _MAX_OBSTACLE_DRAWS."""
    for _ in range(_MAX_OBSTACLE_DRAWS):
        walls = draw()
        if (~walls).sum() >= room:
            return walls
    raise ConfigError(
        f"{what} is not allowed here: {_MAX_OBSTACLE_DRAWS} draws left fewer than {room} free cells "
        f"(agents and targets) of {n}x{n}"
    )


@dataclass(frozen=True)
class IidObstacles:
    """Each cell a wall with probability `density`, independently (n × n uniforms); with `connected`, the cells
    outside the largest 4-connected free region become walls. Density 0 draws nothing."""

    kind: ClassVar[str] = "iid"
    density: float = 0.0
    connected: bool = False

    def __call__(self, n: int, room: int, rng: np.random.Generator) -> np.ndarray | None:
        """(n, n) bool, True on obstacles, or None without obstacles."""
        if self.density <= 0:
            return None

        def draw() -> np.ndarray:
            walls = rng.random((n, n)) < self.density
            return ~largest_region(~walls) if self.connected else walls

        return _until_room(
            draw,
            room,
            f"scenario.obstacles.density={self.density}" + (" with connected=true" if self.connected else ""),
            n,
        )

    def check(self, config: WorldConfig) -> None:
        need(
            finite(self.density) and 0 <= self.density < 1,
            "scenario.obstacles.density",
            self.density,
            "0 <= density < 1",
        )
        need(isinstance(self.connected, bool), "scenario.obstacles.connected", self.connected, "true or false")
        # Agents and targets need distinct free cells in the smallest world: checked at the expected density here,
        # exactly at every reset (the draw repeats until they fit).
        _check_room(config, 1.0 - self.density, "scenario.obstacles.density", self.density)

    @property
    def label(self) -> str:
        return f"iid{self.density:g}{'c' if self.connected else ''}" if self.density > 0 else ""


def _check_room(config: WorldConfig, free_share: float, name: str, value: object) -> None:
    n = config.world_size[0]
    free = int(n * n * free_share)
    room = config.n_agents + config.n_targets[1]
    need(
        room <= free,
        name,
        value,
        f"agents and targets start on distinct cells: n_agents + max targets = {room} must fit the about {free} "
        f"free cells of the smallest world (n={n})",
    )


@dataclass(frozen=True)
class PrimalObstacles:
    """PRIMAL's law: a density d ~ triangular(0, 0.33, 0.5) per map (one uniform), iid walls at d, connected."""

    kind: ClassVar[str] = "primal"

    def __call__(self, n: int, room: int, rng: np.random.Generator) -> np.ndarray:
        def draw() -> np.ndarray:
            density = rng.triangular(0.0, 0.33, 0.5)
            return ~largest_region(~(rng.random((n, n)) < density))

        return _until_room(draw, room, "PRIMAL's walls", n)

    def check(self, config: WorldConfig) -> None:
        _check_room(config, 0.4, "scenario.obstacles.kind", self.kind)  # a connected draw at d = 0.5 keeps ~40 %

    @property
    def label(self) -> str:
        return "primal"


@dataclass(frozen=True)
class MazeObstacles:
    """A maze of corridors `corridor` cells wide between one-cell walls: a randomised depth-first search over a
    lattice of (n + 1) // (corridor + 1) cells a side carves a spanning tree, then each remaining inner wall is
    opened with probability `loops`; cells beyond the lattice are walls. Connected by construction."""

    kind: ClassVar[str] = "maze"
    corridor: int = 3
    loops: float = 0.1

    def __call__(self, n: int, room: int, rng: np.random.Generator) -> np.ndarray:
        return _until_room(lambda: self.draw(n, rng), room, f"scenario.obstacles.corridor={self.corridor}", n)

    def draw(self, n: int, rng: np.random.Generator) -> np.ndarray:
        step = self.corridor + 1
        side = max(1, (n + 1) // step)
        walls = np.ones((n, n), bool)
        for i in range(side):
            for j in range(side):
                walls[i * step : i * step + self.corridor, j * step : j * step + self.corridor] = False
        seen = np.zeros((side, side), bool)
        stack = [(int(rng.integers(side)), int(rng.integers(side)))]
        seen[stack[0]] = True
        while stack:
            i, j = stack[-1]
            around = [
                (i + di, j + dj)
                for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1))
                if 0 <= i + di < side and 0 <= j + dj < side and not seen[i + di, j + dj]
            ]
            if not around:
                stack.pop()
                continue
            ni, nj = around[int(rng.integers(len(around)))]
            self._open(walls, (i, j), (ni, nj))
            seen[ni, nj] = True
            stack.append((ni, nj))
        for i in range(side):  # loops: open each inner wall still standing with probability `loops`
            for j in range(side):
                for ni, nj in ((i + 1, j), (i, j + 1)):
                    if ni < side and nj < side and rng.random() < self.loops:
                        self._open(walls, (i, j), (ni, nj))
        return walls

    def _open(self, walls: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> None:
        """Remove the wall between lattice cells a and b (neighbours)."""
        step, width = self.corridor + 1, self.corridor
        (i, j), (ni, nj) = a, b
        if ni != i:  # vertical neighbours: the wall row between them
            row = max(i, ni) * step - 1
            walls[row, j * step : j * step + width] = False
        else:
            col = max(j, nj) * step - 1
            walls[i * step : i * step + width, col] = False

    def check(self, config: WorldConfig) -> None:
        need(
            is_int(self.corridor) and 1 <= self.corridor <= 16,
            "scenario.obstacles.corridor",
            self.corridor,
            "an integer 1 <= corridor <= 16 (cells)",
        )
        need(finite(self.loops) and 0 <= self.loops <= 1, "scenario.obstacles.loops", self.loops, "0 <= loops <= 1")
        # Exact: the lattice's side² open squares of corridor² cells and the side² − 1 openings of its spanning
        # tree are free in every draw. One lattice cell is no maze (an open room), so the smallest world needs two.
        n = config.world_size[0]
        side, width = (n + 1) // (self.corridor + 1), self.corridor
        need(
            side >= 2,
            "scenario.obstacles.corridor",
            self.corridor,
            f"at most {(n + 1) // 2 - 1} in the smallest "
            f"world (n={n}): two corridors and a wall a side, else the maze is one open room",
        )
        _check_room(
            config,
            (side * side * width * width + (side * side - 1) * width) / (n * n),
            "scenario.obstacles.corridor",
            self.corridor,
        )

    @property
    def label(self) -> str:
        return f"maze{self.corridor}l{self.loops:g}"


@dataclass(frozen=True)
class RoomObstacles:
    """Rooms and corridors by recursive division: a region at least `room_size` on its longer side is split by a
    one-cell wall across it at a random place, with a door `door` cells wide at a random place in the wall, and
    each half divided again. Every region keeps a door to its sibling, so the free cells are connected."""

    kind: ClassVar[str] = "rooms"
    room_size: int = 12
    door: int = 3

    def __call__(self, n: int, room: int, rng: np.random.Generator) -> np.ndarray:
        # Walls abutting a door from both sides could close it: the largest region keeps every free cell reachable
        return _until_room(lambda: ~largest_region(~self.draw(n, rng)), room, f"rooms of {self.room_size}", n)

    def draw(self, n: int, rng: np.random.Generator) -> np.ndarray:
        walls = np.zeros((n, n), bool)
        regions = [(0, 0, n, n)]  # (row, col, height, width)
        while regions:
            r, c, h, w = regions.pop()
            if max(h, w) < self.room_size or min(h, w) < 3:
                continue
            if h >= w:  # a horizontal wall at row r + k, 1 <= k <= h - 2, its door at a random column
                k = int(rng.integers(1, h - 1))
                walls[r + k, c : c + w] = True
                start = int(rng.integers(0, max(1, w - self.door + 1)))
                walls[r + k, c + start : c + start + self.door] = False
                regions += [(r, c, k, w), (r + k + 1, c, h - k - 1, w)]
            else:
                k = int(rng.integers(1, w - 1))
                walls[r : r + h, c + k] = True
                start = int(rng.integers(0, max(1, h - self.door + 1)))
                walls[r + start : r + start + self.door, c + k] = False
                regions += [(r, c, h, k), (r, c + k + 1, h, w - k - 1)]
        return walls

    def check(self, config: WorldConfig) -> None:
        need(
            is_int(self.room_size) and 4 <= self.room_size <= 1024,
            "scenario.obstacles.room_size",
            self.room_size,
            "an integer 4 <= room_size <= 1024 (cells)",
        )
        need(
            is_int(self.door) and 1 <= self.door < self.room_size,
            "scenario.obstacles.door",
            self.door,
            "an integer 1 <= door < room_size (cells)",
        )
        n = config.world_size[0]
        need(
            self.room_size <= n,
            "scenario.obstacles.room_size",
            self.room_size,
            f"at most the smallest world's side n={n}: a larger room is never divided, and the world is one open room",
        )
        _check_room(config, 0.8, "scenario.obstacles.room_size", self.room_size)

    @property
    def label(self) -> str:
        return f"rooms{self.room_size}d{self.door}"


OBSTACLES: Registry[type] = Registry(
    "scenario.obstacles.kind", (IidObstacles, PrimalObstacles, MazeObstacles, RoomObstacles), key="kind"
)
