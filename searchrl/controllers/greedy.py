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

import numpy as np

from searchrl.controllers.base import ControllerConfig, FallbackHeuristic
from searchrl.controllers.greedy_kernels import GreedyMemory, GreedyParams, greedy_actions, reach_weights
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.footprint import GAMMA, MOVES, SUPPORT, team_sensing_rate
from searchrl.world.parallel import world_threads
from searchrl.world.seen import remember_sightings
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams


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
    def __init__(
        self,
        config: WorldConfig,
        horizon: int = GreedyConfig.horizon,
        discount: float = GreedyConfig.discount,
        w_p: float = GreedyConfig.w_p,
        w_u: float = GreedyConfig.w_u,
        w_t: float = GreedyConfig.w_t,
        contested: float = GreedyConfig.contested,
        reach: float = GreedyConfig.reach,
        seen: bool = GreedyConfig.seen,
        age: float = GreedyConfig.age,
        hedge: float = GreedyConfig.hedge,
        seed: int | WorldStreams = 0,
    ) -> None:
        view = config.fov // 2
        if not 1 <= horizon <= view:
            raise ConfigError(f"horizon={horizon!r} is not allowed: 1 <= horizon <= {view} (half the view)")
        if not 0 < discount <= 1:
            raise ConfigError(f"discount={discount!r} is not allowed: 0 < discount <= 1")
        if not all(0 <= w < math.inf for w in (w_p, w_u, w_t)) or w_p + w_u + w_t == 0:
            raise ConfigError(f"w_p={w_p}, w_u={w_u}, w_t={w_t} are not allowed: all >= 0, not all 0")
        if not 0 <= contested <= 1:
            raise ConfigError(f"contested={contested!r} is not allowed: 0 <= contested <= 1")
        if not 0 <= reach <= 4:
            raise ConfigError(f"reach={reach!r} is not allowed: 0 <= reach <= 4 (0: every cell counts the same)")
        if not 0 <= age <= 4:
            raise ConfigError(f"age={age!r} is not allowed: 0 <= age <= 4 (0: a belief does not age)")
        if not 0 <= hedge <= 1:
            raise ConfigError(f"hedge={hedge!r} is not allowed: 0 <= hedge <= 1 (0: the belief as it is)")
        if (seen or age > 0) and not config.bayesian_sensing:
            raise ConfigError(
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
        self._params = GreedyParams(
            MOVES,
            config.n_actions,
            GAMMA,
            self.horizon,
            self.discount,
            self.w_p,
            self.w_u,
            self.w_t,
            view,
            self.contested,
            self.hedge,
        )
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

    def copy_memory(self, into: FootprintGreedy, index: np.ndarray, agents: np.ndarray | None = None) -> None:
        """This rule's per-world memory (reach weights, sightings, ages, rates, the prior's mean) of worlds `index`
        (len = `into`'s batch) copied into `into`, a rule of the same settings over another batch (a planner's
        imagined worlds), so it plays on as this one would; of the agents `agents` (len, k) only where given (the
        per-agent arrays). An array its setting turns off (empty) is left as it is."""
        for name in ("_weights", "_seen", "_known", "_rates", "_flat"):
            source = getattr(self, name)
            if source.shape[0] > int(index.max(initial=0)):
                per_agent = name in ("_seen", "_known") and agents is not None
                setattr(into, name, source[index[:, None], agents].copy() if per_agent else source[index].copy())

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
            remember_sightings(
                state.arrays(),
                SUPPORT,
                self._seen,
                self._known,
                self.config.fov // 2,
                self.config.explicit_area // 2,
                self.age > 0,
                0,
                state.n_worlds,
            )
        return GreedyMemory(self._weights, self._seen, self._known, self._rates, self._flat)

    def fill(self, state: WorldState, fallback: np.ndarray, out: np.ndarray) -> None:
        greedy_actions(state.arrays(), self._params, self.remember(state), fallback, out, world_threads())
