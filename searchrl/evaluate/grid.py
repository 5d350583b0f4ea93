"""The Table 2 grid: world sizes with their target and distribution counts, team sizes N = 1, 2, 4, … up to
each size's limit (§6.3), and the fixed map seeds of each cell."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from searchrl.world.config import ConfigError

CELL_FILE_RE = re.compile(r"n\d+_N\d+\.parquet")  # the file name of a finished cell (Cell.key)


@dataclass(frozen=True)
class Cell:
    n: int  # world side
    n_agents: int  # N
    n_targets: int
    n_distributions: int  # m

    @property
    def key(self) -> str:
        return f"n{self.n}_N{self.n_agents}"


def table2_cells(
    world_sizes: list[int], n_targets: list[int], n_distributions: list[int], max_agents: list[int]
) -> list[Cell]:
    """Cells of the grid in order: for each world size, N doubling from 1 to its max (Table 3's NaNs excluded)."""
    lengths = {len(world_sizes), len(n_targets), len(n_distributions), len(max_agents)}
    if len(lengths) != 1:
        raise ValueError(
            f"grid lists differ in length: world_sizes={world_sizes}, n_targets={n_targets}, "
            f"n_distributions={n_distributions}, max_agents={max_agents}; give one entry per world size"
        )
    if not world_sizes:
        raise ConfigError("grid.world_sizes=[] is not allowed: one or more world sizes (with their other lists)")
    if len(set(world_sizes)) != len(world_sizes):
        raise ConfigError(f"grid.world_sizes={world_sizes} is not allowed: each size once (a cell is named n<n>_N<N>)")
    cells = []
    for n, targets, dists, top in zip(world_sizes, n_targets, n_distributions, max_agents, strict=True):
        if min(n, targets, dists, top) < 1:
            raise ValueError(f"grid entry n={n}, targets={targets}, m={dists}, max N={top}: all must be >= 1")
        if top & (top - 1):  # N doubles from 1: another largest team would not be run, yet be recorded
            raise ConfigError(
                f"grid.max_agents={max_agents} is not allowed: each a power of two (N = 1, 2, 4, … up to it), not {top}"
            )
        agents = 1
        while agents <= top:
            cells.append(Cell(n, agents, targets, dists))
            agents *= 2
    return cells


def map_seed(base: int, cell_index: int, map_index: int) -> int:
    """Seed of one evaluation map; cells never share maps, and the base keeps them apart from training seeds."""
    return base + 100_000 * cell_index + map_index


def cell_files(out_dir: str | Path) -> list[Path]:
    """The finished cells of an evaluation folder, `<out_dir>/cells/<cell>.parquet`, sorted. Only names a cell can
    have count: a writer's hidden temporary (complete or not) or any other file there is never read."""
    return sorted(p for p in Path(out_dir).glob("cells/*.parquet") if CELL_FILE_RE.fullmatch(p.name))
