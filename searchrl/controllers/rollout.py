"""`controller=rollout`: a rollout planner on the team's posterior, the agents deciding one at a time.

At every step the agents of a world choose their moves one at a time (Bertsekas' multiagent rollout, arXiv
1910.00120): agent i scores each of its moves with the moves already chosen by agents 0..i−1 fixed and agents
i+1..N−1 on the base rule (B's teacher by default), everyone then playing the base rule for the rest of `horizon`
steps (0: to the episode's end) in imagined copies of the world whose unfound targets are redrawn from the team's
posterior (searchrl/controllers/posterior.py). A move's score (`value=expected`) is the targets the team can expect
to find along the path it imagines, an exact sum over where the unfound targets lie, so its only noise is the rule's
own random moves and tie-breaks (`value=sampled` counts the imagined targets found instead). Every move is scored
with the same random numbers (common random numbers); every candidate × sample × world of the batch is one world of
one `SearchWorld`, stepped by the compiled engine. With more than one sample, sampling stops early, in rounds of
`chunk`, where one move leads every other by `stop` standard errors of the paired difference; an agent leaves the
base move for any move of a higher mean paired gain. `team` limits
the imagined worlds to the deciding agent and its nearest teammates, for large teams. Centralised: it reads the
whole team's positions and knowledge, never the true targets (unless `truth`, the privileged probe's scores, for
tests and probes only).

A rollout of a base policy is never worse than the base in expectation; on B's teacher-open cells it finds more
than the teacher and every rule (docs/results.md). Cost: N × 5 × samples imagined worlds per step of a real world
(× team/N agents each), each stepped up to `horizon` steps: `python -m searchrl.bench eval --controller rollout`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

import numpy as np

from searchrl.controllers.base import Controller, ControllerConfig
from searchrl.controllers.posterior import (
    PER_AGENT,
    CommonStreams,
    expected_finds,
    posterior_targets,
    remember_prior_u,
)
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams, random_source


@dataclass
class RolloutConfig(ControllerConfig):
    name: str = "rollout"
    base: str = "greedy_target"  # the rule the imagined worlds play on (any registered heuristic)
    base_settings: dict[str, Any] = field(default_factory=lambda: {"reach": 2.0})  # B's teacher
    # Imagined worlds per move, at most. With value=expected a score's only noise is the rule's random moves and
    # tie-breaks: 4 samples score as 1 does at 6.6 times the cost (analysis/rollout_probe.py, 80 x 4)
    samples: int = 1
    horizon: int = 0  # steps imagined from the decision, the decision's included (0: to the episode's end)
    chunk: int = 8  # samples per round of the early stop
    stop: float = 3.0  # stop sampling once the leading move leads every other by this many standard errors (0: never)
    # expected: a path's expected finds under the team's posterior (no sampling noise; tests/test_rollout.py checks
    # it against the sampled mean); sampled: the imagined targets' finds
    value: str = "expected"
    # Who is rolled out with the deciding agent: 0, the whole team; k, the agent and its k − 1 nearest teammates
    # (the others leave the imagined worlds: k agents stepped instead of N, their sensing not counted)
    team: int = 0
    truth: bool = False  # score moves in the true world (the privileged probe): tests and probes only


# The registry's `make_controller`, given to the planner by the registry (it builds its base rule from it)
RuleFactory = Callable[..., Controller]


class Rollout:
    """One-agent-at-a-time rollout of a base rule on the team's posterior; `Controller` protocol."""

    def __init__(
        self, config: WorldConfig, seed: int | WorldStreams = 0, *, rules: RuleFactory, **settings: Any
    ) -> None:
        values = {**asdict(RolloutConfig()), **settings}
        values["base_settings"] = dict(values["base_settings"] or {})
        if values["base"] == "rollout":
            raise ConfigError("controller.base='rollout' is not allowed: the planner's base is a rule")
        samples, horizon, chunk = int(values["samples"]), int(values["horizon"]), int(values["chunk"])
        if samples < 1 or horizon < 0 or chunk < 1 or values["stop"] < 0:
            raise ConfigError(
                f"samples={samples}, horizon={horizon}, chunk={chunk}, stop={values['stop']} are not allowed: "
                "samples >= 1, horizon >= 0, chunk >= 1, stop >= 0"
            )
        if values["value"] not in ("expected", "sampled") or (values["truth"] and values["value"] != "sampled"):
            raise ConfigError(f"value={values['value']!r} is not allowed: expected or sampled (truth needs sampled)")
        if not 0 <= int(values["team"]) <= config.n_agents:
            raise ConfigError(f"team={values['team']!r} is not allowed: 0 (the whole team) to N = {config.n_agents}")
        self.config, self.samples, self.horizon, self.chunk = config, samples, horizon, min(chunk, samples)
        self.stop = float(values["stop"])
        self.value, self.truth = values["value"], bool(values["truth"])
        self.team = int(values["team"]) if 0 < int(values["team"]) < config.n_agents else 0
        self.rules, self.base_name, self.base_settings = rules, values["base"], values["base_settings"]
        self.base = rules(self.base_name, config, seed=seed, settings=self.base_settings, key="controller.base")
        self.rng = random_source(seed)  # one key per world and step: the episode's own stream
        self.prior_u = np.zeros((0, 0, 0))
        # The rollouts' work, for `python -m searchrl.bench eval`: imagined agent-steps, the seconds spent stepping
        # the imagined worlds and their rule, imagined batch steps, Σ their batch sizes, agents per imagined world
        self.work = {"agent_steps": 0, "seconds": 0.0, "steps": 0, "worlds": 0, "agents": config.n_agents}
        self._imagined: dict[tuple[int, int], tuple[SearchWorld, Any]] = {}

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        self.base.reset(state, mask)
        self.prior_u = remember_prior_u(self.prior_u, state, mask)

    def act(self, state: WorldState, maps, vector, active: np.ndarray | None = None) -> np.ndarray:
        if self.prior_u.shape != state.u.shape:
            self.reset(state, np.ones(state.n_worlds, bool))
        base = self.base.act(state, maps, vector)
        keys = self.rng.integers(0, 2**31, size=(state.n_worlds, 1))[:, 0]
        live = state.n_found < state.n_targets
        if active is not None:
            live &= active
        return self.plan(state, np.flatnonzero(live), base, keys)

    def plan(self, state: WorldState, worlds: np.ndarray, base: np.ndarray, keys: np.ndarray) -> np.ndarray:
        """(K, N) moves: base (K, N) with the agents of `worlds` choosing one at a time, world k's samples drawn
        from keys[k] (the same samples for every agent of a step, so each agent sees the moves before its own
        played out in the worlds it imagines)."""
        chosen = base.copy()
        if worlds.size == 0:
            return chosen
        targets = self.imagine(state, worlds, keys)
        for agent in range(state.n_agents):
            members = self.members(state, worlds, agent)  # (W, k) ascending
            first = self.first(chosen, worlds, np.full(worlds.size, agent), members)
            scores = self.score(state, worlds, first, targets, [[int(keys[w])] for w in worlds], members)
            chosen[worlds, agent] = choose(scores, base[worlds, agent], 0.0)
        return chosen

    def first(self, moves: np.ndarray, worlds: np.ndarray, agents: np.ndarray, members: np.ndarray) -> np.ndarray:
        """(G, A, k) the first joint moves of group g: its members' moves[worlds[g]], agent agents[g] taking each
        of the A moves."""
        n_actions = self.config.n_actions
        first = np.repeat(moves[worlds[:, None], members][:, None, :], n_actions, axis=1)
        rows, choices = np.arange(worlds.size)[:, None], np.arange(n_actions)[None, :]
        first[rows, choices, np.argmax(members == agents[:, None], axis=1)[:, None]] = choices
        return first

    def members(self, state: WorldState, worlds: np.ndarray, agent: int) -> np.ndarray:
        """(W, k) the agents rolled out when `agent` decides in each world of `worlds`, in index order: the whole
        team, or the agent and its team − 1 nearest teammates (Chebyshev distance, ties to the lower index)."""
        n_agents = state.n_agents
        if not self.team:
            return np.tile(np.arange(n_agents), (worlds.size, 1))
        gap = np.abs(state.pos[worlds] - state.pos[worlds, agent][:, None, :]).max(axis=2)  # (W, N)
        gap[:, agent] = -1  # the agent itself first
        nearest = np.argsort(gap * n_agents + np.arange(n_agents), axis=1, kind="stable")[:, : self.team]
        return np.sort(nearest, axis=1)

    def imagine(self, state: WorldState, worlds: np.ndarray, keys: np.ndarray) -> list[np.ndarray]:
        """Per world of `worlds`, (samples, T, 2) int64 target cells: the unfound ones redrawn from the team's
        posterior per sample (or the true ones with `truth`), the found ones where they are."""
        h, out = state.halo, []
        for w in worlds:
            n = int(state.size[w])
            inner = (w, slice(h, h + n), slice(h, h + n))
            cells = np.repeat(state.target_pos[w][None], self.samples, axis=0)
            lost = np.flatnonzero(state.target_valid[w] & ~state.target_found[w])
            if not self.truth and lost.size:
                free = ~state.blocked[inner] & ~state.found_grid[inner]
                rng = np.random.default_rng([int(keys[w]), 1 << 20])
                draws = posterior_targets(state.p[inner], self.prior_u[inner], free, lost.size, self.samples, rng)
                cells[:, lost] = np.stack(draws)
            out.append(cells)
        return out

    def score(
        self,
        state: WorldState,
        worlds: np.ndarray,
        first: np.ndarray,
        targets: list[np.ndarray],
        keys: list,
        members: np.ndarray | None = None,
    ) -> np.ndarray:
        """(W, C, M) targets found by the end of the horizon when world worlds[g] starts with joint move first[g, c]
        (W, C, k) of its agents members[g] (W, k) (default: the whole team) and the base rule plays on, in
        M <= samples imagined copies (NaN past the early stop); sample j of world g draws the same numbers for every
        candidate. `keys[g]` seeds world g's numbers."""
        n_groups, n_cand = first.shape[:2]
        if members is None:
            members = np.tile(np.arange(state.n_agents), (n_groups, 1))
        rounds = []
        todo = np.arange(n_groups)
        for start in range(0, self.samples, self.chunk):
            m = min(self.chunk, self.samples - start)
            picked = [targets[int(g)][start : start + m] for g in todo]
            streams = [[*keys[g], start] for g in todo]
            found = self.play(state, worlds[todo], first[todo], picked, streams, m, members[todo])
            block = np.full((n_groups, n_cand, m), np.nan)
            block[todo] = found
            rounds.append(block)
            scores = np.concatenate(rounds, axis=2)
            todo = todo[~clear(scores[todo], self.stop)] if self.stop > 0 else todo
            if todo.size == 0:
                break
        return scores

    def play(
        self,
        state: WorldState,
        worlds: np.ndarray,
        first: np.ndarray,
        targets: list[np.ndarray],
        keys: list,
        m: int,
        members: np.ndarray,
    ) -> np.ndarray:
        """(G, C, m) found at the horizon's end: imagined world (g·m + j)·C + c is real world worlds[g] with its
        agents members[g] (G, k) only, sample j's targets and first joint move first[g, c] (G, C, k)."""
        n_groups, n_cand, k = first.shape
        count = n_groups * m * n_cand
        if (count, k) not in self._imagined:  # the imagined batch and its rule, kept while the size holds (only
            # the last size: an evaluation's batch shrinks as episodes end, and each size is a copy of every map)
            config = replace(self.config, n_agents=k)
            world = SearchWorld(config, count, auto_reset=False, observe=False)
            base = self.rules(self.base_name, config, settings=self.base_settings, key="controller.base")
            base.reset(world.state, np.ones(count, bool))
            self._imagined = {(count, k): (world, base)}
        world, base = self._imagined[count, k]
        world.started = True
        source = np.repeat(worlds, m * n_cand)
        agents = np.repeat(members, m * n_cand, axis=0)  # (count, k)
        whole = k == state.n_agents
        for f in fields(WorldState):
            value = getattr(state, f.name)
            if not (isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == state.n_worlds):
                continue
            if f.name in PER_AGENT and not whole:
                getattr(world.state, f.name)[:] = value[source[:, None], agents]
            else:
                np.take(value, source, axis=0, out=getattr(world.state, f.name))
        if not whole:  # the occupancy grid of the agents kept, numbered as in the imagined world
            h, occupant, pos = state.halo, world.state.occupant, world.state.pos
            occupant.fill(-1)
            occupant[np.arange(count)[:, None], pos[..., 0] + h, pos[..., 1] + h] = np.arange(k)[None, :]
        world.state.target_pos[:] = np.repeat(np.concatenate(targets), n_cand, axis=0)
        world.rng = CommonStreams([[*key, 0] for key in keys], m, n_cand)
        base.rng = CommonStreams([[*key, 1] for key in keys], m, n_cand)
        if hasattr(self.base, "copy_memory"):  # a rule that remembers (Controller's optional copy_memory)
            self.base.copy_memory(base, source, None if whole else agents)
        # Worlds of one batch may be at different steps (an evaluation starts an episode where one ends): each
        # imagined world's score is its finds when its own horizon ends.
        end = np.full(count, self.config.max_steps)
        if self.horizon:
            end = np.minimum(end, state.t[source] + self.horizon)
        p_end = np.empty_like(world.state.p) if self.value == "expected" else None
        clock = time.perf_counter()
        world.step(np.repeat(first[:, None], m, axis=1).reshape(-1, k))  # order (g·m + j)·C + c
        found = world.state.n_found.copy()
        while ((world.state.t < end) & ((world.state.n_found < world.state.n_targets) | (p_end is not None))).any():
            if p_end is not None:
                ending = world.state.t == end
                p_end[ending] = world.state.p[ending]
            world.step(base.act(world.state, None, None))
            counts = world.state.t <= end
            found[counts] = world.state.n_found[counts]
        steps = int(world.state.t.max() - state.t[source].min())
        self.work["seconds"] += time.perf_counter() - clock
        self.work["steps"] += steps
        self.work["worlds"] += steps * count
        self.work["agent_steps"] += steps * count * k
        self.work["agents"] = k
        if p_end is not None:
            ending = world.state.t == end
            p_end[ending] = world.state.p[ending]
            found = state.n_found[source] + expected_finds(state, self.prior_u, worlds, p_end).reshape(-1)
        return found.reshape(n_groups, m, n_cand).transpose(0, 2, 1).astype(np.float64)


def clear(scores: np.ndarray, stop: float) -> np.ndarray:
    """(G,) bool: the leading candidate's paired lead over every other exceeds `stop` standard errors, or no
    candidate differs from another in any sample; scores (G, C, M) with NaN for samples not drawn."""
    m = np.isfinite(scores[:, 0]).sum(axis=1)
    mean = np.nanmean(scores, axis=2)
    lead = mean.argmax(axis=1)
    gap = scores[np.arange(len(scores)), lead][:, None, :] - scores  # (G, C, M)
    spread = np.nanstd(gap, axis=2, ddof=1) if scores.shape[2] > 1 else np.zeros(mean.shape)
    sure = np.nanmean(gap, axis=2) > stop * spread / np.sqrt(np.maximum(m, 1))[:, None]
    sure[np.arange(len(scores)), lead] = True
    same = np.nanmax(np.abs(gap), axis=(1, 2)) == 0
    return (sure.all(axis=1) & (m > 1)) | same


def choose(scores: np.ndarray, base: np.ndarray, confidence: float) -> np.ndarray:
    """(G,) the chosen candidate from scores (G, C, M) (NaN for samples not drawn): the base candidate `base` (G,)
    unless another's mean paired gain over it is positive and above `confidence` standard errors; then the best."""
    rows = np.arange(len(scores))
    gain = scores - scores[rows, base][:, None, :]
    m = np.isfinite(gain).sum(axis=2)
    mean = np.nanmean(gain, axis=2)
    error = (np.nanstd(gain, axis=2, ddof=1) if gain.shape[2] > 1 else np.zeros(mean.shape)) / np.sqrt(np.maximum(m, 1))
    sure = np.where((mean > 0) & (mean > confidence * error), mean, 0.0)
    return np.where(sure.max(axis=1) > 0, sure.argmax(axis=1), base)
