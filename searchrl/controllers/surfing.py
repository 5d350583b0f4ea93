"""Information surfing (§6.1.3, after the lab's grid version): each agent climbs the gradient of the information
in its own belief, pooled at several scales, pushed away from the agents it sees by a Coulomb-like force.

Per agent: information I = w_p·p̂ + w_u·û of its belief (p̂, û scaled as in the observation). At each scale s the
four blocks of side s centred s cells east, west, south and north are averaged (from a 3×3 grid of samples per
block, so every scale costs the same), and the central difference gives a gradient, normalised to unit length.
The unit gradients are averaged over scales; then `repulsion` × the unit vector of Σ (a_i − a_j)/|a_i − a_j|³
over the agents in the field of view is added. The agent takes the move best aligned with the sum among moves to
free cells it can see; with no gradient and no neighbour it moves at random.

The default scales (1, 3) keep every sample inside the agent's 11×11 field of view: a greedy local climb, as the
paper describes surfing (§6.1.3, §6.3), and what a policy sees. Wider scales also pull agents toward information far
away; on the paper's grid that leaves more behind (docs/results.md, "The baselines").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from searchrl.controllers.base import ControllerConfig, FallbackHeuristic
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.footprint import MOVES
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams


@njit(cache=True)
def _info(belief, k, i, r, c, sp, su, wp, wu):
    side = belief.shape[3]
    if r < 0 or c < 0 or r >= side or c >= side:
        return 0.0
    return wp * belief[k, i, 0, r, c] * sp + wu * belief[k, i, 1, r, c] * su


@njit(cache=True)
def _block_mean(belief, k, i, r, c, s, sp, su, wp, wu):
    """Mean information of the s×s block centred at padded (r, c), from a 3×3 grid of samples."""
    step = s // 3
    total = 0.0
    for a in range(-1, 2):
        for b in range(-1, 2):
            total += _info(belief, k, i, r + a * step, c + b * step, sp, su, wp, wu)
    return total / 9.0


@njit(cache=True)
def surfing_actions(w, moves, n_actions, scales, wp, wu, repulsion, view, fallback, out):
    """out (K,N) int64 <- surfing actions of the agents of w (`WorldState.arrays()`); moves (A,2) int64, scales (L,)
    int64 block sides, `view` half the field of view. fallback (K,N) int64: random moves used where there is
    nothing to follow."""
    belief, obs_scale, occupant, blocked, pos, h = w.belief, w.obs_scale, w.occupant, w.blocked, w.pos, w.halo
    n_worlds, n_agents = pos.shape[0], pos.shape[1]
    for k in range(n_worlds):
        sp, su = obs_scale[k, 0], obs_scale[k, 1]
        for i in range(n_agents):
            r, c = pos[k, i, 0] + h, pos[k, i, 1] + h
            gx, gy = 0.0, 0.0
            for s in scales:
                east = _block_mean(belief, k, i, r, c + s, s, sp, su, wp, wu)
                west = _block_mean(belief, k, i, r, c - s, s, sp, su, wp, wu)
                south = _block_mean(belief, k, i, r + s, c, s, sp, su, wp, wu)
                north = _block_mean(belief, k, i, r - s, c, s, sp, su, wp, wu)
                dx, dy = east - west, south - north
                norm = math.sqrt(dx * dx + dy * dy)
                if norm > 1e-12:
                    gx += dx / norm / len(scales)
                    gy += dy / norm / len(scales)
            fx, fy = 0.0, 0.0
            for a in range(-view, view + 1):
                for b in range(-view, view + 1):
                    j = occupant[k, r + a, c + b]
                    if j >= 0 and j != i:
                        d = math.sqrt(a * a + b * b)
                        fx -= b / d**3
                        fy -= a / d**3
            fnorm = math.sqrt(fx * fx + fy * fy)
            if fnorm > 0.0:
                gx += repulsion * fx / fnorm
                gy += repulsion * fy / fnorm
            if gx * gx + gy * gy < 1e-24:
                out[k, i] = fallback[k, i]
                continue
            best, best_score = 0, -1e300
            for a in range(1, n_actions):
                tr, tc = r + moves[a, 0], c + moves[a, 1]
                if blocked[k, tr, tc] or occupant[k, tr, tc] >= 0:
                    continue
                mr, mc = moves[a, 0], moves[a, 1]
                score = (mc * gx + mr * gy) / math.sqrt(mr * mr + mc * mc)
                if score > best_score:
                    best, best_score = a, score
            out[k, i] = best


@dataclass
class SurfingConfig(ControllerConfig):
    """Settings of `controller=surfing` (InformationSurfing's keyword arguments)."""

    name: str = "surfing"
    # Block sides of the pooled gradients. [1, 3] stays inside the 11×11 field of view (the policy's window) and is
    # the paper's greedy local surfing; [1, 3, 9, 27] also follows the information up to 40 cells away and finds
    # less on most cells of the grid (docs/results.md, "The baselines").
    scales: list[int] = field(default_factory=lambda: [1, 3])
    w_p: float = 0.6  # weight of probability in the information surfed
    w_u: float = 0.4  # weight of uncertainty
    repulsion: float = 0.4  # weight of the unit Coulomb push away from visible agents


class InformationSurfing(FallbackHeuristic):
    """Batched information-surfing controller; parameters are config values of `controller=surfing`."""

    # Defaults are SurfingConfig's (the schema `controller=surfing` composes), read from it, written once.
    def __init__(
        self,
        config: WorldConfig,
        scales: tuple[int, ...] | None = None,
        w_p: float = SurfingConfig.w_p,
        w_u: float = SurfingConfig.w_u,
        repulsion: float = SurfingConfig.repulsion,
        seed: int | WorldStreams = 0,
    ) -> None:
        scales = SurfingConfig().scales if scales is None else scales
        if not scales or min(scales) < 1:
            raise ConfigError(f"scales={list(scales)!r} is not allowed: one or more positive block sizes")
        if not (0 <= w_p < math.inf and 0 <= w_u < math.inf and 0 <= repulsion < math.inf) or w_p + w_u == 0:
            raise ConfigError(
                f"w_p={w_p}, w_u={w_u}, repulsion={repulsion} are not allowed: finite, >= 0, w_p + w_u > 0"
            )
        super().__init__(config, seed)
        self.scales = np.asarray(scales, np.int64)
        self.w_p, self.w_u, self.repulsion = w_p, w_u, repulsion

    def fill(self, state: WorldState, fallback: np.ndarray, out: np.ndarray) -> None:
        surfing_actions(
            state.arrays(),
            MOVES,
            self.config.n_actions,
            self.scales,
            self.w_p,
            self.w_u,
            self.repulsion,
            self.config.fov // 2,
            fallback,
            out,
        )
