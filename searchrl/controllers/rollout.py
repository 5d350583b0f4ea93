"""Rollout-greedy: one step of policy improvement over footprint-greedy, planned on the agent's whole belief.

For each move to a free cell, the agent imagines taking it and then following footprint-greedy (the controller's
own settings: horizon, discount, weights, reach) for `rollout` − 1 more steps, and counts what its footprint
would sense on the way: Σ_s rollout_discount^s Σ_Γ Γ(d)·m(x_s + d), each imagined sensing scaling m under the
footprint by (1 − Γ), as sensing scales the belief (λk = 1). m = reach · I is greedy's information of the
agent's own belief, over the whole world. It takes the move whose rollout senses most (Bertsekas' rollout
algorithm: in this model of sensing, the improved policy does at least as well as the greedy it imagines, for a
lone agent).

Why it is here (issue 29): the best local controllers find about half of the cell bound on the hard cells, and how
much of the rest a path could close was not known. The imagined greedy walks beyond the 11×11 view and meets the
mass there, so the first move is chosen with the whole belief, what the whole-belief context shows a policy. It
measures what planning with that knowledge gains over the teacher, and would be the teacher of a context policy
if it gained. Not a local controller.

What the rollout leaves out: the other agents (they neither sense nor block in it; in model B they share the
belief, so two agents may plan the same lane), unless `mates` > 0: then the teammates in the agent's view, up to
`mates` of them, walk greedily beside it on its belief and what they sense counts too (one agent's step of
multiagent rollout; the agents still decide at once, each assuming the others follow greedy). It leaves out the
true belief refresh in Φ too; it reads the belief with greedy's `seen` and `age` where set, and refuses
`contested` and `far`. Where the imagined greedy sees nothing in its view it stops (the real one walks at
random); where no move's rollout senses anything the agent walks at random.

What it measured (docs/results.md, "Planning with the whole belief"): on the hard cells a lone agent gains at
most about 0.02 over target-greedy with horizon 5, and teams lose, with or without `mates` and `age`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from searchrl.controllers.greedy import FootprintGreedy, GreedyTargetConfig, cell_information
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import GAMMA
from searchrl.world.state import WorldState

MAX_ROLLOUT = 256  # an episode's length: a rollout never needs more
MAX_MATES = 8  # teammates imagined per agent (each multiplies the imagined steps)


@dataclass
class GreedyRolloutConfig(GreedyTargetConfig):
    """Settings of `controller=greedy_rollout`: target-greedy's, planned over `rollout` imagined steps."""

    name: str = "greedy_rollout"
    rollout: int = 32  # steps imagined per candidate move (the first one included), at most MAX_ROLLOUT
    rollout_discount: float = 1.0  # weight of what the s-th imagined step senses: rollout_discount^s
    # Teammates in the agent's view (up to this many, nearest first) imagined following greedy beside it, and
    # what they sense counted (one agent's step of multiagent rollout); 0: the agent imagines itself alone.
    mates: int = 0
    # A probe, not a decentralized controller: imagine the nearest teammates wherever they are, not only in view.
    mates_anywhere: bool = False


@njit(cache=True)
def _information_map(w, params, memory, k, i, m):
    """m (S, S) <- greedy's information reach·I of agent i's belief in world k, every cell (`cell_information`)."""
    belief, sp, su, now = w.belief, w.obs_scale[k, 0], w.obs_scale[k, 1], w.t[k]
    reach, seen, known = memory.reach, memory.seen, memory.known
    rate = memory.rates[k] if known.shape[2] > 0 else 0.0
    for r in range(m.shape[0]):
        for c in range(m.shape[1]):
            m[r, c] = reach[k, r, c] * cell_information(params, belief, sp, su, seen, known, rate, now, k, i, r, c)


@njit(cache=True)
def _sensed(gamma, m, r, c, r0, c0, view):
    """Σ_Γ Γ(d)·m(r + d, c + d) over the cells within `view` rows and columns of (r0, c0)."""
    g, side = gamma.shape[0] // 2, m.shape[0]
    total = 0.0
    for dr in range(-g, g + 1):
        for dc in range(-g, g + 1):
            rr, cc = r + dr, c + dc
            if abs(rr - r0) <= view and abs(cc - c0) <= view and 0 <= rr < side and 0 <= cc < side:
                total += gamma[dr + g, dc + g] * m[rr, cc]
    return total


@njit(cache=True)
def _greedy_move(params, blocked, m, r, c):
    """Footprint-greedy's move from padded (r, c) on the map m, inside its view: the action, or -1 with nothing
    to sense there."""
    gamma, moves, view = params.gamma, params.moves, params.fov_half
    best, best_score = -1, 0.0
    for a in range(1, params.n_actions):
        mr, mc = moves[a, 0], moves[a, 1]
        if blocked[r + mr, c + mc]:
            continue
        score, lane = 0.0, 1.0
        for t in range(1, params.horizon + 1):
            score += lane * _sensed(gamma, m, r + t * mr, c + t * mc, r, c, view)
            lane *= params.discount
        if score > best_score:
            best, best_score = a, score
    return best


@njit(cache=True)
def _sense(gamma, m, r, c, log_cell, log_value, n_log):
    """A footprint at padded (r, c): returns (what it senses of m, entries logged), m scaled by (1 − Γ) under it
    and each change logged from entry n_log on."""
    g, side = gamma.shape[0] // 2, m.shape[0]
    sensed = 0.0
    for dr in range(-g, g + 1):
        for dc in range(-g, g + 1):
            rr, cc = r + dr, c + dc
            weight = gamma[dr + g, dc + g]
            if 0 <= rr < side and 0 <= cc < side and weight > 0.0:
                sensed += weight * m[rr, cc]
                log_cell[n_log, 0], log_cell[n_log, 1], log_value[n_log] = rr, cc, m[rr, cc]
                n_log += 1
                m[rr, cc] *= 1.0 - weight
    return sensed, n_log


@njit(cache=True)
def _imagine(params, blocked, m, log_cell, log_value, r, c, mates, n_mates, steps, discount):
    """What the team senses, step s weighted discount^s, while the agent stands at padded (r, c) and then follows
    greedy for steps − 1 more steps, and the teammates at mates[:n_mates] (padded rows, cols; overwritten) follow
    greedy from their first step, each moving and sensing before the agent, all on the information map m (S, S),
    which each imagined sensing scales by (1 − Γ); every change is logged in log_cell/log_value so the caller can
    undo it. Returns (value, entries logged)."""
    moves = params.moves
    value, weight, n_log, me = 0.0, 1.0, 0, True
    for s in range(steps):
        for j in range(n_mates):  # teammates in view, as the agent imagines them: greedy on its own belief
            if mates[j, 0] < 0:
                continue
            a = _greedy_move(params, blocked, m, mates[j, 0], mates[j, 1])
            if a < 0:
                mates[j, 0] = -1  # nothing left in its view: it drops out of the imagined team
                continue
            mates[j, 0], mates[j, 1] = mates[j, 0] + moves[a, 0], mates[j, 1] + moves[a, 1]
            sensed, n_log = _sense(params.gamma, m, mates[j, 0], mates[j, 1], log_cell, log_value, n_log)
            value += weight * sensed
        if me and s > 0:  # greedy's move from (r, c) on what is left, inside its view
            a = _greedy_move(params, blocked, m, r, c)
            me = a >= 0  # nothing left in view: the imagined greedy would wander, and stops
            if me:
                r, c = r + moves[a, 0], c + moves[a, 1]
        if me:
            sensed, n_log = _sense(params.gamma, m, r, c, log_cell, log_value, n_log)
            value += weight * sensed
        elif n_mates == 0:
            break
        weight *= discount
    return value, n_log


@njit(cache=True)
def rollout_actions(w, params, memory, rollout, discount, n_mates, mate_range, max_steps, fallback, out, m, mates,
                    log_cell, log_value):  # fmt: skip
    """out (K, N) int64 <- rollout-greedy actions of the agents of w (`WorldState.arrays()`) with greedy settings
    `params` (GreedyParams), `memory` (GreedyMemory, brought to this step) and up to n_mates teammates within
    mate_range rows and columns imagined; fallback (K, N) int64 random moves used where no rollout senses
    anything. Scratch: m (S, S) float64, mates (n_mates, 2) int64, log_cell (L, 2) int64 and log_value (L,)
    float64, L >= rollout · 25 · (1 + n_mates)."""
    pos, occupant, moves = w.pos, w.occupant, params.moves
    near = np.empty((pos.shape[1], 3), np.int64)  # teammates within mate_range: Chebyshev distance, padded row, col
    no_one = np.zeros(0, np.int64)  # their order when none is imagined
    for k in range(pos.shape[0]):
        steps = min(rollout, max(1, max_steps - w.t[k]))
        for i in range(pos.shape[1]):
            _information_map(w, params, memory, k, i, m)
            r, c = pos[k, i, 0] + w.halo, pos[k, i, 1] + w.halo
            n_view, order = 0, no_one
            if n_mates > 0:  # the other agents within mate_range (the view: as channel 0 of the observation shows)
                for j in range(pos.shape[1]):
                    apart = max(abs(pos[k, j, 0] - pos[k, i, 0]), abs(pos[k, j, 1] - pos[k, i, 1]))
                    if j != i and apart <= mate_range:
                        near[n_view, 0], near[n_view, 1] = apart, pos[k, j, 0] + w.halo
                        near[n_view, 2] = pos[k, j, 1] + w.halo
                        n_view += 1
                order = np.argsort(near[:n_view, 0], kind="mergesort")  # nearest first, ties by index
                n_view = min(n_view, n_mates)
            best, best_value = -1, 0.0
            for a in range(1, params.n_actions):
                mr, mc = moves[a, 0], moves[a, 1]
                if w.blocked[k, r + mr, c + mc] or occupant[k, r + mr, c + mc] >= 0:
                    continue
                for j in range(n_view):
                    mates[j, 0], mates[j, 1] = near[order[j], 1], near[order[j], 2]
                value, n_log = _imagine(params, w.blocked[k], m, log_cell, log_value, r + mr, c + mc, mates, n_view,
                                        steps, discount)  # fmt: skip
                for e in range(n_log - 1, -1, -1):  # undo, newest first, so a cell sensed twice ends as it began
                    m[log_cell[e, 0], log_cell[e, 1]] = log_value[e]
                if value > best_value:
                    best, best_value = a, value
            out[k, i] = best if best >= 1 else fallback[k, i]


class GreedyRollout(FootprintGreedy):
    """FootprintGreedy improved by one rollout step over the agent's whole belief (module docstring)."""

    def __init__(self, config: WorldConfig, rollout: int = 32, rollout_discount: float = 1.0, mates: int = 0,
                 mates_anywhere: bool = False, contested: float = 1.0, far: bool = False,
                 **greedy: object) -> None:  # fmt: skip
        if not 1 <= rollout <= MAX_ROLLOUT:
            raise ValueError(f"rollout={rollout!r} is not allowed: 1 <= rollout <= {MAX_ROLLOUT} (an episode's length)")
        if not 0 < rollout_discount <= 1:
            raise ValueError(f"rollout_discount={rollout_discount!r} is not allowed: 0 < rollout_discount <= 1")
        if not 0 <= mates <= MAX_MATES:
            raise ValueError(f"mates={mates!r} is not allowed: 0 <= mates <= {MAX_MATES} (teammates imagined)")
        if contested != 1 or far:
            raise ValueError(f"contested={contested!r}, far={far!r} are not allowed with rollout: its imagined "
                             "greedy reads the belief alone (contested=1) and all of it (far=false)")  # fmt: skip
        super().__init__(config, **greedy)
        self.rollout, self.rollout_discount, self.mates = int(rollout), float(rollout_discount), int(mates)
        self.mates_anywhere = bool(mates_anywhere)
        self._map = np.zeros((0, 0))
        entries = self.rollout * GAMMA.size * (1 + self.mates)  # every imagined footprint of one candidate move
        self._log_cell, self._log_value = np.zeros((entries, 2), np.int64), np.zeros(entries)
        self._mates = np.zeros((self.mates, 2), np.int64)

    def fill(self, state: WorldState, fallback: np.ndarray, out: np.ndarray) -> None:
        memory, side = self.remember(state), state.blocked.shape[-1]
        if self._map.shape != (side, side):
            self._map = np.zeros((side, side))
        mate_range = side if self.mates_anywhere else self.config.fov // 2
        rollout_actions(state.arrays(), self._params, memory, self.rollout, self.rollout_discount, self.mates,
                        mate_range, self.config.max_steps, fallback, out, self._map, self._mates, self._log_cell,
                        self._log_value)  # fmt: skip
