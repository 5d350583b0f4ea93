"""Context-greedy: target-greedy that also reads the whole-belief context, the heuristic a context policy is measured
against (issue 29: "the policy beats the heuristics" compares equals).

Each agent sees its own belief pooled to G × G bins and where its field of view sits, exactly the context a policy
with `env.world.context` = G observes (searchrl/world/context.py). Both options are put in one unit, the
information a footprint senses per step (Σ_Γ Γ·I, I = w_p·p̂ + w_u·û + w_t·p̂·(1 − û) as greedy scores it):

- staying: greedy's best move scores S over its horizon, so it senses `S / Σ_t discount^t` per step;
- a bin b wholly outside the agent's view (what the view shows greedy already weighs): sweeping fresh ground there
  senses about `ΣΓ · I_b` per step, I_b from the bin's pooled p̂ and û, but only after the d_b moves to its
  centre, so over the R steps left it is worth `ΣΓ · I_b · (1 − d_b / R)` per step.

An agent heads for the best bin when that is worth `margin` times staying (a pooled mean overstates what a bin
holds: its mass sits in a few cells, and other agents may head for it too; with 2 it still trails target-greedy
where teams are larger, docs/results.md "A heuristic with the same view") and keeps that aim until it stands in
the bin (an aim dropped whenever the view looked richer, or once the bin came into view, made agents step to and
fro at the edge of their view), then takes greedy's moves again. Where its view holds little, greedy follows the
faint slopes there; this one walks to the best remaining mass. Moves are one axis at a time (the longer way
first), or diagonal in the diagonal model.

With `divide`, a bin that a teammate in the agent's view stands nearer to is not a candidate: teammates that see
each other (in model B, those whose beliefs just merged, which rank the bins alike) split the ground ahead as a
Voronoi partition of their positions would, instead of walking to the same bin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from searchrl.controllers.greedy import FootprintGreedy, GreedyTargetConfig
from searchrl.world.config import WorldConfig
from searchrl.world.context import CONTEXT_CHANNELS, context_into
from searchrl.world.footprint import GAMMA, MOVES
from searchrl.world.state import WorldState


@dataclass
class GreedyContextConfig(GreedyTargetConfig):
    """Settings of `controller=greedy_context`: target-greedy's, the context's resolution G and the margin."""

    name: str = "greedy_context"
    context: int = 16  # G: bins per side of the pooled belief it reads (the policies' env.world.context)
    margin: float = 2.0  # leave the view for a bin only when the bin is worth this many times staying (1: any gain)
    divide: bool = False  # skip bins a teammate in view stands nearer to (a Voronoi split of the ground ahead)


_ACTION_OF = np.full((3, 3), 99, np.int64)  # (dr + 1, dc + 1) -> the action with that move (99: none)
for _a, (_dr, _dc) in enumerate(MOVES.tolist()):
    _ACTION_OF[_dr + 1, _dc + 1] = _a


class ContextGreedy(FootprintGreedy):
    """FootprintGreedy that heads for the best pooled bin of its own belief when that beats its view."""

    def __init__(
        self, config: WorldConfig, context: int = 16, margin: float = 2.0, divide: bool = False, **greedy: object
    ) -> None:
        if not 2 <= context <= min(64, config.world_size[0]):
            raise ValueError(f"context={context!r} is not allowed: 2 <= G <= min(64, smallest world size "
                             f"{config.world_size[0]})")  # fmt: skip
        if not margin >= 1:
            raise ValueError(f"margin={margin!r} is not allowed: margin >= 1 (1: leave for any bin worth more)")
        super().__init__(config, **greedy)
        self.context, self.margin, self.divide = int(context), float(margin), bool(divide)
        self._steps = sum(self.discount**t for t in range(self.horizon))  # greedy's score / this = per step
        self._pooled = np.zeros((0, 0, CONTEXT_CHANNELS, self.context, self.context), np.float32)
        self._goal = np.full((0, 0), -1, np.int64)  # (K, N) flat bin each agent heads for, -1: none

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        super().reset(state, mask)
        if self._goal.shape == (state.n_worlds, state.n_agents):
            self._goal[mask] = -1

    def fill(self, state: WorldState, fallback: np.ndarray, out: np.ndarray) -> None:
        super().fill(state, fallback, out)
        k, n, grid = state.n_worlds, state.n_agents, self.context
        if self._pooled.shape[:2] != (k, n):
            self._pooled = np.zeros((k, n, CONTEXT_CHANNELS, grid, grid), np.float32)
            self._goal = np.full((k, n), -1, np.int64)
        context_into(state.belief, state.obs_scale, state.pos, state.size, state.halo, self.config.fov, self._pooled)
        p, u, view = (self._pooled[:, :, c].astype(np.float64) for c in range(CONTEXT_CHANNELS))
        info = self.w_p * p + self.w_u * u + self.w_t * p * np.clip(1.0 - u, 0.0, None)  # (K, N, G, G)
        side = state.size.astype(np.float64)[:, None, None]  # (K, 1, 1)
        centre = (np.arange(grid) + 0.5) * side / grid  # (K, 1, G) bin centres, in cells
        rows = centre[..., :, None] - state.pos[:, :, 0, None, None]  # (K, N, G, 1) moves to go, by row bin
        cols = centre[..., None, :] - state.pos[:, :, 1, None, None]  # (K, N, 1, G)
        apart = np.maximum(abs(rows), abs(cols)) if self.config.diagonal else abs(rows) + abs(cols)
        left = np.maximum(self.config.max_steps - state.t, 1).astype(np.float64)[:, None, None, None]
        worth = float(GAMMA.sum()) * info * np.clip(1.0 - apart / left, 0.0, None)
        worth = np.where(view > 0, 0.0, worth)
        if self.divide:
            worth = np.where(self._nearer_teammate(state, np.broadcast_to(apart, worth.shape)), 0.0, worth)
        worth = worth.reshape(k, n, -1)  # (K, N, G²) per step, as greedy's rate
        staying = self.scores / self._steps  # (K, N)
        bin_of = state.pos * grid // state.size[:, None, None]  # (K, N, 2) the bin each agent stands in
        here = bin_of[..., 0] * grid + bin_of[..., 1]
        self._goal[self._goal == here] = -1  # arrived: greedy works the bin from here
        best = worth.argmax(axis=2)
        start = (self._goal < 0) & (np.take_along_axis(worth, best[..., None], axis=2)[..., 0] > self.margin * staying)
        self._goal[start] = best[start]
        go, aim = self._goal >= 0, np.maximum(self._goal, 0)
        to_row = (aim // grid + 0.5) * side[:, :, 0] / grid - state.pos[..., 0]  # (K, N)
        to_col = (aim % grid + 0.5) * side[:, :, 0] / grid - state.pos[..., 1]
        dr, dc = np.sign(np.round(to_row)).astype(np.int64), np.sign(np.round(to_col)).astype(np.int64)
        if not self.config.diagonal:  # one axis at a time: the longer way to go
            along_rows = abs(to_row) >= abs(to_col)
            dr, dc = np.where(along_rows, dr, 0), np.where(along_rows, 0, dc)
        target = state.pos + np.stack([dr, dc], axis=-1) + state.halo  # (K, N, 2) padded
        worlds = np.arange(k)[:, None]
        free = ~state.blocked[worlds, target[..., 0], target[..., 1]]
        free &= state.occupant[worlds, target[..., 0], target[..., 1]] < 0
        action = _ACTION_OF[dr + 1, dc + 1]
        chosen = go & free & ((dr != 0) | (dc != 0)) & (action < self.config.n_actions)
        out[chosen] = action[chosen]

    def _nearer_teammate(self, state: WorldState, apart: np.ndarray, most: int = 4) -> np.ndarray:
        """(K, N, G, G): a teammate in the agent's view (up to the `most` nearest) stands nearer to the bin, or as
        near with a lower index. `apart` (K, N, G, G) holds each agent's moves to each bin. Teammates that see each
        other split the ground ahead between them, as a Voronoi partition would, and walk apart."""
        k, n = state.n_worlds, state.n_agents
        gap = abs(state.pos[:, :, None, :] - state.pos[:, None, :, :]).max(axis=-1)  # (K, N, N) Chebyshev
        seen = (gap <= self.config.fov // 2) & ~np.eye(n, dtype=bool)
        most = min(most, n - 1)
        if most < 1:
            return np.zeros(apart.shape, bool)
        order = np.argsort(np.where(seen, gap, np.iinfo(np.int64).max), axis=2, kind="stable")[:, :, :most]
        valid = np.take_along_axis(seen, order, axis=2)  # (K, N, M)
        theirs = apart[np.arange(k)[:, None, None], order]  # (K, N, M, G, G)
        mine = apart[:, :, None]
        lower = order < np.arange(n)[None, :, None]  # (K, N, M) the teammate wins ties
        nearer = (theirs < mine) | ((theirs == mine) & lower[..., None, None])
        return (nearer & valid[..., None, None]).any(axis=2)
