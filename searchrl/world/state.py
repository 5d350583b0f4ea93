"""The batched world state: K worlds × N agents as plain numpy arrays.

Layout. Every map is padded by `h = config.halo` cells on each side and sized for the largest world the config
can draw, so windows (Γ, Φ, FOV, communication) never need bounds checks: cell (row, col) of world k lives at
`[k, row + h, col + h]`. Cells outside a world (the halo and, for a world smaller than the allocation, the
cells beyond its side n) have p = u = 0 and are marked `blocked`, which is also what the observation shows
as "obstacle or out of bounds". Positions are stored unpadded.

The arrays are updated in place by `searchrl.world.step` (copying a (K, N, 2, S, S) belief per step would
cost more than the step itself).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields
from operator import attrgetter

import numpy as np
from numba import njit, types
from numba.experimental import structref

from searchrl.world.config import ConfigError, WorldConfig


@dataclass
class WorldState:
    """State of K worlds with N agents. S = largest side + 2·halo, T = largest target count."""

    size: np.ndarray  # (K,) int64, side n of each world
    t: np.ndarray  # (K,) int64, steps taken in the current episode
    p: np.ndarray  # (K, S, S) float32, true probability map
    u: np.ndarray  # (K, S, S) float32, true uncertainty map
    blocked: np.ndarray  # (K, S, S) bool, obstacle or outside the world
    belief: np.ndarray  # (K, N, 2, S, S) float32, each agent's (p, u) map
    # Bounding box (r0, r1, c0, c1), inclusive, padded, of the cells where an agent's belief may differ from
    # the prior; empty when r0 > r1. A neighbour can only lower cells inside its box, so the merge scans the
    # union of the neighbours' boxes instead of the whole map.
    belief_box: np.ndarray  # (K, N, 4) int64
    # The same for the cells where an agent's belief may have changed since its world's last merge (what that merge
    # lowered, and the Φ refreshes since), its position at that merge, and whether world k has merged since its
    # reset: a neighbour kept since then is scanned only on its news (searchrl/world/merge.py). Code that edits
    # beliefs by hand sets merged[k] false.
    belief_news: np.ndarray  # (K, N, 4) int64
    merge_pos: np.ndarray  # (K, N, 2) int64, unpadded
    merged: np.ndarray  # (K,) bool
    # Step at which each agent last saw a cell's truth in Φ (0: never), for `belief_age`; (K, N, 0, 0) when off.
    belief_time: np.ndarray  # (K, N, S, S) int32
    # Π (1 − Γ) over the neighbours' footprints each agent saw since it last saw a cell's truth, for
    # `belief_seen` (searchrl/world/seen.py); (K, N, 0, 0) when off.
    belief_seen: np.ndarray  # (K, N, S, S) float32
    age_rate: np.ndarray  # (K,) float64, belief_age · N · ΣΓ / free cells (0: beliefs do not age)
    pos: np.ndarray  # (K, N, 2) int64, agent (row, col), unpadded
    occupant: np.ndarray  # (K, S, S) int32, index of the agent on a cell or -1
    target_pos: np.ndarray  # (K, T, 2) int64, target (row, col), unpadded
    target_valid: np.ndarray  # (K, T) bool, slot holds a target this episode
    target_found: np.ndarray  # (K, T) bool
    found_grid: np.ndarray  # (K, S, S) bool, cells holding a found target
    swept: np.ndarray  # (K, S, S) bool, cells under any footprint since the reset (searchrl/world/swept.py)
    n_targets: np.ndarray  # (K,) int64
    n_found: np.ndarray  # (K,) int64
    obs_scale: np.ndarray  # (K, 2) float32, 1 / max of the prior p and u (observation scaling)
    # Episode accumulators (team totals), read by `episode_metrics`.
    ep_return: np.ndarray  # (K,) float64, sum of all agents' rewards
    ep_comm_pairs: np.ndarray  # (K,) int64, F: neighbour pairs summed over steps
    ep_info: np.ndarray  # (K,) float64, Σ over steps and agents of M_p + M_u
    ep_collisions: np.ndarray  # (K,) int64, blocked moves
    ep_stale: np.ndarray  # (K,) int64, agent-steps whose footprint swept no new free cell
    halo: int  # padding h on each side of every map

    @property
    def n_worlds(self) -> int:
        return self.size.shape[0]

    @property
    def n_agents(self) -> int:
        return self.pos.shape[1]

    def __setattr__(self, name: str, value: object) -> None:
        if self.__dict__.get(name) is not value:  # a field rebound (`state.t += 1` is not): rebuild `arrays()`
            self.__dict__.pop("_arrays", None)
        object.__setattr__(self, name, value)

    def __getstate__(self) -> dict:
        """Pickle and deepcopy the fields only: the kernels' view is rebuilt on first use."""
        return {name: value for name, value in self.__dict__.items() if name != "_arrays"}

    def arrays(self) -> WorldArrays:
        """The same arrays (not copies) as one `WorldArrays`, the argument through which the compiled kernels take
        the state; built on first use and kept until a field is rebound."""
        view = self.__dict__.get("_arrays")
        if view is None:
            view = self.__dict__["_arrays"] = _world_arrays(_GET_FIELDS(self))
        return view

    def copy(self) -> WorldState:
        """A deep copy (tests and oracles compare against it)."""
        return WorldState(
            **{f.name: np.copy(v) if isinstance(v := getattr(self, f.name), np.ndarray) else v for f in fields(self)}
        )


@structref.register
class WorldArraysType(types.StructRef):
    """The numba type of `WorldArrays`."""

    def preprocess_fields(self, fields: tuple) -> tuple:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class WorldArrays(structref.StructRefProxy):
    """WorldState's fields as one numba object (a kernel reads `w.pos`, `w.halo`, ... with the shapes documented
    above): numba does not take a dataclass. A StructRef rather than a named tuple: a call types and unboxes it in
    constant time (under 1 µs, where a named tuple of 24 arrays cost about 5 µs a kernel call, some 10% of a step
    on the bench's cases), and it passes to an inner compiled function as one pointer. Read it in compiled code
    only: from Python each field is a compiled call."""


_FIELDS = tuple(f.name for f in fields(WorldState))
_GET_FIELDS = attrgetter(*_FIELDS)
structref.define_proxy(WorldArrays, WorldArraysType, _FIELDS)


@njit(cache=True)
def _world_arrays(values):
    """WorldArrays of `values`, WorldState's fields in order (a compiled, cached constructor)."""
    return WorldArrays(*values)


def physical_memory() -> int:
    """Bytes of RAM on this machine (0 where the platform does not say)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 0


def allocate(config: WorldConfig, n_worlds: int) -> WorldState:
    """Zeroed arrays for `n_worlds` worlds; `reset_worlds` fills them. Memory is dominated by the beliefs:
    K · N · 2 · S² · 4 bytes (K · N · 3 · S² · 4 with `belief_age`, K · N · 4 · S² · 4 with `belief_seen` too)."""
    if n_worlds < 1:
        raise ConfigError(f"n_worlds={n_worlds!r} is not allowed: need at least 1 world")
    k, n = n_worlds, config.n_agents
    h = config.halo
    side = config.world_size[1] + 2 * h
    layers = 2 + (config.belief_age > 0) + config.belief_seen
    need_bytes, have = k * n * layers * side * side * 4, physical_memory()
    if have and need_bytes > have:  # numpy would fail with a bare allocation error, or the machine swap to a halt
        raise ConfigError(
            f"n_worlds={k}, n_agents={n}, world_size={config.world_size} is not allowed here: the agents' beliefs "
            f"alone need {need_bytes / 2**30:,.1f} GiB and this machine has {have / 2**30:,.1f} GiB; fewer worlds, "
            "agents or a smaller largest world"
        )
    t_max = config.n_targets[1]
    state = WorldState(
        size=np.zeros(k, np.int64),
        t=np.zeros(k, np.int64),
        p=np.zeros((k, side, side), np.float32),
        u=np.zeros((k, side, side), np.float32),
        blocked=np.ones((k, side, side), bool),
        belief=np.zeros((k, n, 2, side, side), np.float32),
        belief_box=np.tile(np.array([side, -1, side, -1], np.int64), (k, n, 1)),
        belief_news=np.tile(np.array([side, -1, side, -1], np.int64), (k, n, 1)),
        merge_pos=np.zeros((k, n, 2), np.int64),
        merged=np.zeros(k, bool),
        belief_time=np.zeros((k, n, side, side) if config.belief_age > 0 else (k, n, 0, 0), np.int32),
        belief_seen=np.ones((k, n, side, side) if config.belief_seen else (k, n, 0, 0), np.float32),
        age_rate=np.zeros(k, np.float64),
        pos=np.zeros((k, n, 2), np.int64),
        occupant=np.full((k, side, side), -1, np.int32),
        target_pos=np.zeros((k, t_max, 2), np.int64),
        target_valid=np.zeros((k, t_max), bool),
        target_found=np.zeros((k, t_max), bool),
        found_grid=np.zeros((k, side, side), bool),
        swept=np.zeros((k, side, side), bool),
        n_targets=np.zeros(k, np.int64),
        n_found=np.zeros(k, np.int64),
        obs_scale=np.ones((k, 2), np.float32),
        ep_return=np.zeros(k, np.float64),
        ep_comm_pairs=np.zeros(k, np.int64),
        ep_info=np.zeros(k, np.float64),
        ep_collisions=np.zeros(k, np.int64),
        ep_stale=np.zeros(k, np.int64),
        halo=h,
    )
    return state
