"""Footprint-greedy search: each agent takes the move whose footprint would sense the most information.

Per agent: information I = w_p·p̂ + w_u·û + w_t·p̂·(1 − û) of its own belief (p̂, û scaled as in the observation,
so û = u / max u on unvisited cells). A move a is scored by what the 5×5 footprint Γ would see if the agent went
on in that direction for `horizon` steps,
Σ_{t=1..horizon} discount^(t-1) Σ_Γ Γ(d)·I(x + t·a + d), counting only cells inside the agent's 11×11 field of
view (what a policy sees). The agent takes the best-scoring move among those to free cells; with nothing to sense
it moves at random.

Which information. The defaults (w_p 0.6, w_u 0.4, w_t 0) blend probability and uncertainty as surfing does.
The term p̂·(1 − û) is proportional to the chance that a target sits in the cell: §4.1.4 keeps a target drawn
from p with probability 1 − u (we read u relative to its maximum, searchrl/world/reset.py), so targets avoid
high uncertainty; sensing scales p and u of a cell by the same factor (1 − Γ), so on a sensed cell p̂·(1 − û)
stays an upper bound of the posterior. With w_p = w_u = 0, w_t = 1 and horizon 3 (the shipped policies'
teacher) greedy scores a move by the targets its footprint expects to detect, and finds clearly more than the
blend (README, "Results: baselines").

Cells nearer (in moves) to another agent in view than to this one count `contested` times their information
(1: no difference). Agents of a team that do not share beliefs (model C) or have not met yet see the same
prior and would chase the same peak; leaving the cells a neighbour reaches first to that neighbour splits the
view between them, using only what the field of view shows (other agents' positions, observation channel 0).

With `seen`, each agent also keeps what it can infer from the neighbours it sees: a neighbour in view sensed
its footprint in the last step, so the agent scales its own p̂ and û there by (1 − Γ), as that sensing did in the
world, and remembers it until the world is reset. In a world that merges beliefs (B) this comes through
communication; in C it is the only way an agent learns what others cleared, and with many agents C's greedy
otherwise re-chases it (README, "Results: the reference policies"). It reads only the observation's channel of
other agents, over time.

With `age` > 0, what an agent believes of a cell counts exp(−age·ρ·(t − t₀)) times, t₀ the last step it saw the
cell's truth (inside its explicit area Φ, where the world refreshes its belief; 0 for cells it never saw) and
ρ = N·ΣΓ / (free cells) the rate at which a team of N spread evenly over the world senses each cell. Without
merging (model C) an agent's belief outside its own path stays the prior, so in a crowded world it chases peaks
that others cleared long ago and leaves the cells it saw partly sensed; ageing the belief makes those known
remainders worth a detour. Inside Φ the neighbours' footprints inferred by `seen` are forgotten, since the
truth there already holds them. With few agents ρ is small and nothing changes. Both maps are kept by
searchrl/world/seen.py, which also keeps the world's `belief_age` and `belief_seen`: with `age` the two are equal.

Cells that fewer footprint positions can sense count more with `reach` > 0: (Γ_total / Γ_reach)^reach, where
Γ_reach is the footprint mass an agent can put on the cell from the cells it may stand on (1.37 on an edge, 1.91
in a corner, above 1 beside obstacles; `reach_weights`). A footprint on the edge senses little, so greedy keeps
off the edge and only brushes it with Γ's outer ring; with many agents most targets it misses lie on the edge
(README, "Results: the reference policies"). Weighting those cells draws an agent onto the edge when it passes.

Why it is here: it is the quantity sensing actually removes (eq. 1 with λk = 1), where surfing follows a pooled
gradient of the same information. On the paper's grid it finds more than surfing on 14 of the 30 cells and less
on none (README, "Results: baselines"), so it is the stronger teacher for a warm start (`imitation.teacher=greedy`).
It is not one of the paper's baselines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from searchrl.controllers.base import ControllerConfig, FallbackHeuristic
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import GAMMA, MOVES, SUPPORT, SUPPORT_DC, SUPPORT_DR, SUPPORT_G, team_sensing_rate
from searchrl.world.parallel import chunk_count, chunk_span, world_threads
from searchrl.world.seen import freshness, remember_sightings
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams


class GreedyParams(NamedTuple):
    """FootprintGreedy's settings as `greedy_actions` takes them."""

    moves: np.ndarray  # (A, 2) int64, MOVES
    n_actions: int  # A: 5, or 9 with diagonal moves
    gamma: np.ndarray  # (5, 5) float64, Γ
    horizon: int
    discount: float
    w_p: float
    w_u: float
    w_t: float
    fov_half: int  # half the field of view: what an agent sees lies within that many cells
    contested: float
    hedge: float  # ε: the information read off (1 − ε)·belief + ε·uniform, both as sensing has depleted them


class GreedyMemory(NamedTuple):
    """What greedy keeps per world and agent between steps (searchrl/world/seen.py for seen and known)."""

    reach: np.ndarray  # (K, S, S) float64, `reach_weights`
    seen: np.ndarray  # (K, N, S, S) float32, Π (1 − Γ) of the neighbours' footprints seen; (K, N, 0, 0) without `seen`
    known: np.ndarray  # (K, N, S, S) int32, step each agent last saw a cell's truth; (K, N, 0, 0) without `age`
    rates: np.ndarray  # (K,) float64, age · N · ΣΓ / free cells: how fast an evenly spread team senses a cell
    flat: np.ndarray  # (K,) float64, the prior's mean information per free cell (with `hedge`; else (0,))


@njit(cache=True)
def _moves_apart(dr, dc, diagonal):
    """Moves between two cells dr, dc apart: Chebyshev with diagonal moves, Manhattan without."""
    return max(abs(dr), abs(dc)) if diagonal else abs(dr) + abs(dc)


@njit(cache=True, inline="always")  # inlined: called per cell, on scalars (an inlined call's array arguments
def information(params, p, u, prior_p, flat_k, sp, su, seen, fresh):  # are counted in and out, ~100 ns a call)
    """I = w_p·p̂ + w_u·û + w_t·p̂·(1 − û) of one cell of an agent's belief, p and u there (`WorldState.belief`),
    p̂ = sp·p·seen·fresh, û = su·u·seen·fresh: the observation's scaling and the factors of what the neighbours it
    saw have sensed there (`seen`) and what unseen agents have likely sensed since it last saw the cell's truth
    (`fresh`), 1.0 where GreedyMemory keeps neither. With params.hedge = ε > 0: (1 − ε)·I + ε·flat_k·left, flat_k
    the prior's mean I per free cell and left = p / prior_p (prior_p: `WorldState.p` there), scaled alike, the share
    of the cell sensing has not yet cleared: greedy on a belief that keeps ε of its mass uniform, depleted by the
    same sensing."""
    p_hat, u_hat = p * sp, u * su
    left = p / prior_p if params.hedge > 0.0 and prior_p > 0.0 else 0.0
    p_hat, u_hat, left = p_hat * seen, u_hat * seen, left * seen
    p_hat, u_hat, left = p_hat * fresh, u_hat * fresh, left * fresh
    info = params.w_p * p_hat + params.w_u * u_hat + params.w_t * p_hat * max(0.0, 1.0 - u_hat)
    if params.hedge > 0.0:
        info = (1.0 - params.hedge) * info + params.hedge * flat_k * left
    return info


@njit(cache=True)
def cell_information(params, belief, prior, flat, sp, su, seen, known, rate, now, k, i, r, c):
    """`information` of agent i's belief at padded cell (r, c) of world k at step `now`, read off the arrays:
    belief and prior `WorldState.belief` and `.p`, flat, seen, known and rate GreedyMemory's (rate its rates[k])."""
    seen_factor = seen[k, i, r, c] if seen.shape[2] > 0 else 1.0
    fresh = freshness(rate, now, known[k, i, r, c]) if known.shape[2] > 0 else 1.0
    flat_k = flat[k] if params.hedge > 0.0 else 0.0
    return information(params, belief[k, i, 0, r, c], belief[k, i, 1, r, c], prior[k, r, c], flat_k, sp, su,
                       seen_factor, fresh)  # fmt: skip


@njit(cache=True)
def view_scratch(params):
    """values (3, W, W) float64, W = 2·(fov_half + g) + 1, Γ of radius g: `view_values`' scratch, one per thread."""
    side = 2 * (params.fov_half + params.gamma.shape[0] // 2) + 1
    return np.zeros((3, side, side))


@njit(cache=True, inline="always")  # inlined: once per agent, so its arguments are not copied
def view_values(w, params, memory, k, i, r0, c0, others, n_others, values):
    """values (3, W, W) <- (x, reach, I) of every cell within params.fov_half rows and columns of agent i's padded
    position (r0, c0) in world k of w (`WorldState.arrays()`), what the agent sees, centred (`view_scratch`): I its
    belief's information (`cell_information`), reach `GreedyMemory.reach`, x = contested where one of the agents
    at others[:n_others] (rows, cols) is fewer moves away than (r0, c0), else 1. Zero on the cells off the grid
    and in the margin outside the view, where footprints centred in the view reach: they add nothing."""
    view, contested, diagonal = params.fov_half, params.contested, params.n_actions > 5
    belief, prior, sp, su, now = w.belief, w.p, w.obs_scale[k, 0], w.obs_scale[k, 1], w.t[k]
    reach, seen, known, flat = memory.reach, memory.seen, memory.known, memory.flat
    rate = memory.rates[k] if known.shape[2] > 0 else 0.0
    margin, side = values.shape[1] // 2 - view, belief.shape[3]
    has_seen, has_known, flat_k = seen.shape[2] > 0, known.shape[2] > 0, flat[k] if params.hedge > 0.0 else 0.0
    values[:] = 0.0
    for dr in range(-view, view + 1):
        for dc in range(-view, view + 1):
            rr, cc = r0 + dr, c0 + dc
            if rr < 0 or cc < 0 or rr >= side or cc >= side:
                continue
            x, mine = 1.0, _moves_apart(dr, dc, diagonal)
            for j in range(n_others):
                if _moves_apart(rr - others[j, 0], cc - others[j, 1], diagonal) < mine:
                    x = contested
                    break
            vr, vc = margin + view + dr, margin + view + dc
            values[0, vr, vc], values[1, vr, vc] = x, reach[k, rr, cc]
            # cell_information's reads, done here: a call taking the arrays would count them in and out per cell
            seen_factor = seen[k, i, rr, cc] if has_seen else 1.0
            fresh = freshness(rate, now, known[k, i, rr, cc]) if has_known else 1.0
            values[2, vr, vc] = information(params, belief[k, i, 0, rr, cc], belief[k, i, 1, rr, cc], prior[k, rr, cc],
                                            flat_k, sp, su, seen_factor, fresh)  # fmt: skip


@njit(cache=True, inline="always")  # inlined: called per move and step ahead
def footprint_information(params, values, dr, dc):
    """Σ Γ(d)·x·reach·I over the footprint centred dr, dc away from the agent whose view `values` holds
    (`view_values`; |dr|, |dc| <= fov_half): what it would sense there, the cells it does not see counting 0."""
    gamma = params.gamma
    g = gamma.shape[0] // 2
    centre = values.shape[1] // 2
    total = 0.0
    for fr in range(-g, g + 1):
        for fc in range(-g, g + 1):
            weight = gamma[fr + g, fc + g]
            if weight > 0.0:  # terms in the order of Γ's rows, as a sum over the cells sensed
                r, c = centre + dr + fr, centre + dc + fc
                total += weight * values[0, r, c] * values[1, r, c] * values[2, r, c]
    return total


@njit(cache=True, parallel=True)
def greedy_actions(w, params, memory, fallback, out, threads):
    """out (K,N) int64 <- footprint-greedy actions of the agents of w (`WorldState.arrays()`) with settings `params`
    (GreedyParams) and `memory` (GreedyMemory, seen and known already brought to this step). fallback (K,N) int64:
    random moves used where nothing is sensed. The K·N agents (world-major) are shared among `threads` numba
    threads (`searchrl.world.parallel.world_threads()`), not the worlds: a team mix holds a few worlds of many
    agents. An agent's move reads the state and writes its own entry of `out` only, so the count changes no bit."""
    n_slots = out.shape[0] * out.shape[1]
    n_chunks = chunk_count(n_slots, n_slots, threads)
    if n_chunks == 1:  # in this thread: waking a worker for the only chunk would just add its wake-up
        _greedy_span(w, params, memory, fallback, out, np.int64(0), n_slots)
        return
    for chunk in prange(n_chunks):
        first, stop = chunk_span(chunk, n_chunks, 0, n_slots)
        _greedy_span(w, params, memory, fallback, out, first, stop)


@njit(cache=True)
def _greedy_span(w, params, memory, fallback, out, first, stop):
    """`greedy_actions` for the agents first..stop-1 of the K·N, world-major (agent i of world k is k·N + i)."""
    pos, occupant, blocked, h, moves, view = w.pos, w.occupant, w.blocked, w.halo, params.moves, params.fov_half
    others = np.empty(((2 * view + 1) ** 2, 2), np.int64)
    values = view_scratch(params)
    for slot in range(first, stop):
        k, i = slot // pos.shape[1], slot % pos.shape[1]
        r, c = pos[k, i, 0] + h, pos[k, i, 1] + h
        n_others = 0
        if params.contested != 1.0:  # the other agents in view, as channel 0 of the observation shows them
            for dr in range(-view, view + 1):
                for dc in range(-view, view + 1):
                    j = occupant[k, r + dr, c + dc]
                    if j >= 0 and j != i:
                        others[n_others, 0], others[n_others, 1] = r + dr, c + dc
                        n_others += 1
        view_values(w, params, memory, k, i, r, c, others, n_others, values)
        best, best_score = -1, 0.0
        for a in range(1, params.n_actions):
            mr, mc = moves[a, 0], moves[a, 1]
            if blocked[k, r + mr, c + mc] or occupant[k, r + mr, c + mc] >= 0:
                continue
            score, weight = 0.0, 1.0
            for t in range(1, params.horizon + 1):
                score += weight * footprint_information(params, values, t * mr, t * mc)
                weight *= params.discount
            if score > best_score:
                best, best_score = a, score
        out[k, i] = best if best >= 1 else fallback[k, i]


def reach_weights(blocked: np.ndarray, exponent: float) -> np.ndarray:
    """(K, S, S) float64 weights (Γ_total / Γ_reach)^exponent from blocked (K, S, S) bool, 0 on blocked cells.

    Γ_reach(x) = Σ_d Γ(d) over the offsets d with x − d free: the footprint mass an agent can put on cell x from
    the cells it can stand on. It is Γ_total inside the world and less on the edge (3.96 of 5.44), in a corner
    (2.85) and beside obstacles. Needs a halo of at least Γ's radius (the state's is half the field of view)."""
    g = GAMMA.shape[0] // 2
    free = ~blocked
    side = blocked.shape[-1]
    mass = np.zeros(blocked.shape, np.float64)
    for dr, dc, weight in zip(SUPPORT_DR, SUPPORT_DC, SUPPORT_G, strict=True):  # mass[x] += Γ(d) · free[x − d]
        mass[:, g : side - g, g : side - g] += weight * free[:, g - dr : side - g - dr, g - dc : side - g - dc]
    weights = np.zeros(blocked.shape, np.float64)
    np.divide(GAMMA.sum(), mass, out=weights, where=free & (mass > 0))
    return np.power(weights, exponent, out=weights, where=free)


@dataclass
class GreedyConfig(ControllerConfig):
    """Settings of `controller=greedy` (FootprintGreedy's keyword arguments)."""

    name: str = "greedy"
    # Not one of the paper's baselines: a move is scored by the information its footprint would sense over the
    # next `horizon` steps in that direction (inside the field of view), later steps weighted by `discount`.
    horizon: int = 2
    discount: float = 0.7
    w_p: float = 0.6  # the same weights as surfing's, so the two differ only in how they read the belief
    w_u: float = 0.4
    # Weight of p̂·(1 − û), the chance a target sits in the cell (§4.1.4 keeps a draw from p with probability
    # 1 − u/max u); w_p=0 w_u=0 w_t=1 scores a move by the targets its footprint expects to detect.
    w_t: float = 0.0
    # Weight of cells another agent in view reaches in fewer moves (1: no difference; < 1 splits the view).
    contested: float = 1.0
    # Cells that fewer footprint positions can sense (edges, corners, beside obstacles) count
    # (Γ_total / Γ_reach)^reach times; 0 counts every cell the same.
    reach: float = 0.0
    # Lower what an agent believes under the footprints of the neighbours it sees, as their sensing would (for
    # worlds without merging, model C).
    seen: bool = False
    # Count what an agent believes of a cell exp(−age · ρ · steps since it last saw the cell's truth) times, ρ the
    # rate at which a team spread evenly senses a cell (for worlds without merging).
    age: float = 0.0
    # Hedge against a wrong prior: read the information off (1 − hedge)·belief + hedge·uniform (0: the belief).
    hedge: float = 0.0


@dataclass
class GreedyTargetConfig(GreedyConfig):
    """Settings of `controller=greedy_target`: target-greedy, footprint-greedy scoring a move by the targets its
    footprint expects to detect over 3 steps (w_p = w_u = 0, w_t = 1), the shipped policies' teacher. The same
    controller as `controller=greedy controller.horizon=3 controller.w_p=0 controller.w_u=0 controller.w_t=1`, and
    recorded as `greedy` with those settings (searchrl/controllers/registry.py)."""

    name: str = "greedy_target"
    horizon: int = 3
    w_p: float = 0.0
    w_u: float = 0.0
    w_t: float = 1.0


class FootprintGreedy(FallbackHeuristic):
    """Batched footprint-greedy controller; parameters are config values of `controller=greedy`."""

    # Defaults are GreedyConfig's (the schema `controller=greedy` composes), read from it, written once.
    def __init__(self, config: WorldConfig, horizon: int = GreedyConfig.horizon,
                 discount: float = GreedyConfig.discount, w_p: float = GreedyConfig.w_p, w_u: float = GreedyConfig.w_u,
                 w_t: float = GreedyConfig.w_t, contested: float = GreedyConfig.contested,
                 reach: float = GreedyConfig.reach, seen: bool = GreedyConfig.seen, age: float = GreedyConfig.age,
                 hedge: float = GreedyConfig.hedge, seed: int | WorldStreams = 0) -> None:  # fmt: skip
        view = config.fov // 2
        if not 1 <= horizon <= view:
            raise ValueError(f"horizon={horizon!r} is not allowed: 1 <= horizon <= {view} (half the view)")
        if not 0 < discount <= 1:
            raise ValueError(f"discount={discount!r} is not allowed: 0 < discount <= 1")
        if not all(0 <= w < math.inf for w in (w_p, w_u, w_t)) or w_p + w_u + w_t == 0:
            raise ValueError(f"w_p={w_p}, w_u={w_u}, w_t={w_t} are not allowed: all >= 0, not all 0")
        if not 0 <= contested <= 1:
            raise ValueError(f"contested={contested!r} is not allowed: 0 <= contested <= 1")
        if not 0 <= reach <= 4:
            raise ValueError(f"reach={reach!r} is not allowed: 0 <= reach <= 4 (0: every cell counts the same)")
        if not 0 <= age <= 4:
            raise ValueError(f"age={age!r} is not allowed: 0 <= age <= 4 (0: a belief does not age)")
        if not 0 <= hedge <= 1:
            raise ValueError(f"hedge={hedge!r} is not allowed: 0 <= hedge <= 1 (0: the belief as it is)")
        if (seen or age > 0) and not config.bayesian_sensing:
            raise ValueError(
                f"seen={seen!r}, age={age!r} are not allowed in this world: both model sensing as p·(1 − Γ), so they "
                f"need lam * k = 1 and k_per_n = 0 (here k={config.k}, k_per_n={config.k_per_n})"
            )
        super().__init__(config, seed)
        self.horizon, self.discount, self.w_p, self.w_u = int(horizon), float(discount), float(w_p), float(w_u)
        self.w_t = float(w_t)
        self.contested = float(contested)
        self.reach = float(reach)
        self.seen = bool(seen)
        self.age, self.hedge = float(age), float(hedge)
        self._params = GreedyParams(MOVES, config.n_actions, GAMMA, self.horizon, self.discount, self.w_p, self.w_u,
                                    self.w_t, view, self.contested, self.hedge)  # fmt: skip
        # GreedyMemory's arrays, sized on the first reset
        self._weights, self._seen = np.ones((0, 0, 0)), np.ones((0, 0, 0, 0), np.float32)
        self._known, self._rates, self._flat = np.zeros((0, 0, 0, 0), np.int32), np.zeros(0), np.zeros(0)

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        if self._weights.shape != state.blocked.shape:
            self._weights, mask = np.ones(state.blocked.shape), np.ones(state.n_worlds, bool)
        if self.reach > 0 and mask.any():  # obstacles and the world's side change only on reset
            self._weights[mask] = reach_weights(state.blocked[mask], self.reach)
        maps, off = state.belief[:, :, 0].shape, (state.n_worlds, state.n_agents, 0, 0)  # kept or not
        if self._seen.shape != (maps if self.seen else off):
            self._seen = np.ones(maps if self.seen else off, np.float32)
        if self._known.shape != (maps if self.age > 0 else off):
            self._known = np.zeros(maps if self.age > 0 else off, np.int32)
        self._seen[mask], self._known[mask] = 1.0, 0
        self._rates = self.age * team_sensing_rate(state.blocked, state.n_agents) if self.age > 0 else np.zeros(0)
        if self.hedge > 0:
            if self._flat.shape != (state.n_worlds,):
                self._flat, mask = np.zeros(state.n_worlds), np.ones(state.n_worlds, bool)
            self._flat[mask] = self.prior_information(state)[mask]

    def prior_information(self, state: WorldState) -> np.ndarray:
        """(K,) float64: the mean information I of the prior (p, u as the observation scales them) per free cell."""
        p_hat, u_hat = state.p * state.obs_scale[:, 0, None, None], state.u * state.obs_scale[:, 1, None, None]
        info = self.w_p * p_hat + self.w_u * u_hat + self.w_t * p_hat * np.maximum(0.0, 1.0 - u_hat)
        return np.where(state.blocked, 0.0, info).sum(axis=(1, 2)) / (~state.blocked).sum(axis=(1, 2))

    def remember(self, state: WorldState) -> GreedyMemory:
        """The memory brought to this step: what each agent saw (forgotten on Φ only with age, as always)."""
        if self._weights.shape != state.blocked.shape or self._seen.shape[:2] != (state.n_worlds, state.n_agents):
            self.reset(state, np.ones(state.n_worlds, bool))
        if self.seen or self.age > 0:
            remember_sightings(state.arrays(), SUPPORT, self._seen, self._known, self.config.fov // 2,
                               self.config.explicit_area // 2, self.age > 0, 0, state.n_worlds)  # fmt: skip
        return GreedyMemory(self._weights, self._seen, self._known, self._rates, self._flat)

    def fill(self, state: WorldState, fallback: np.ndarray, out: np.ndarray) -> None:
        greedy_actions(state.arrays(), self._params, self.remember(state), fallback, out, world_threads())
