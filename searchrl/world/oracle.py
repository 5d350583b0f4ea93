"""A deliberately plain reference implementation of one step and of the observation, from SPEC.md only.

Every rule is an explicit Python loop over worlds, agents, targets and cells so that a reader can check it
against `searchrl/world/SPEC.md` line by line; it is slow on purpose and shares no code with the engine
beyond the spec's own constants (Γ and the move table). `oracle_step` mutates the state it is given, like
the engine's `step`: tests hand it their own `state.copy()`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from searchrl.world.config import WorldConfig
from searchrl.world.footprint import GAMMA, MOVES
from searchrl.world.state import WorldState


class OracleResult(NamedTuple):
    """Same fields and dtypes as the engine's StepResult."""

    reward: np.ndarray  # (K, N) float32
    terminated: np.ndarray  # (K,) bool
    truncated: np.ndarray  # (K,) bool
    collided: np.ndarray  # (K, N) bool
    targets_found: np.ndarray  # (K, N) int64
    info_collected: np.ndarray  # (K, N) float64, M_p + M_u
    comm_gain: np.ndarray  # (K, N) float64, ΔM_p + ΔM_u
    comm_pairs: np.ndarray  # (K,) int64


def _is_blocked_cell(state: WorldState, k: int, row: int, col: int) -> bool:
    """Obstacle or outside [0, n)² of world k (SPEC step 1)."""
    n = int(state.size[k])
    if not (0 <= row < n and 0 <= col < n):
        return True
    return bool(state.blocked[k, row + state.halo, col + state.halo])


def _move(state: WorldState, k: int, actions: np.ndarray, priority: np.ndarray) -> list[bool]:
    """SPEC step 1 for world k: returns blocked[i] and writes the new positions and `occupant`."""
    n_agents = state.n_agents
    start = [(int(state.pos[k, i, 0]), int(state.pos[k, i, 1])) for i in range(n_agents)]
    proposal = [(r + int(MOVES[a][0]), c + int(MOVES[a][1])) for (r, c), a in zip(start, actions[k], strict=True)]
    moving = [int(a) != 0 for a in actions[k]]
    # The first two tests: a blocked cell, or a cell some agent stands on at the start of the step.
    passed = [
        moving[i] and not _is_blocked_cell(state, k, *proposal[i]) and proposal[i] not in start for i in range(n_agents)
    ]
    blocked = [moving[i] and not passed[i] for i in range(n_agents)]
    # The third test: a contender that passed the first two and has a higher priority takes the cell
    # (an exact tie, which float64 draws make practically impossible, goes to the lower index).
    for i in range(n_agents):
        if not passed[i]:
            continue
        for j in range(n_agents):
            if j != i and passed[j] and proposal[j] == proposal[i] and (priority[k, j], -j) > (priority[k, i], -i):
                blocked[i] = True
    h = state.halo
    for i in range(n_agents):
        if moving[i] and not blocked[i]:
            state.pos[k, i] = proposal[i]
    state.occupant[k] = -1
    for i in range(n_agents):
        state.occupant[k, state.pos[k, i, 0] + h, state.pos[k, i, 1] + h] = i
    return blocked


def _detect(state: WorldState, k: int, detect: np.ndarray) -> list[int]:
    """SPEC step 2: sequential independent detection with one uniform draw per target (Γ is the detection
    probability of §3.1). Returns the number of targets credited to each agent."""
    h = state.halo
    credited = [0] * state.n_agents
    for t in range(state.target_valid.shape[1]):
        if not state.target_valid[k, t] or state.target_found[k, t]:
            continue
        r, c = int(state.target_pos[k, t, 0]), int(state.target_pos[k, t, 1])
        s = 1.0
        for i in range(state.n_agents):
            dr, dc = r - int(state.pos[k, i, 0]), c - int(state.pos[k, i, 1])
            if abs(dr) > 2 or abs(dc) > 2 or GAMMA[dr + 2, dc + 2] <= 0:
                continue
            s *= 1.0 - float(GAMMA[dr + 2, dc + 2])
            if detect[k, t] < 1.0 - s:
                credited[i] += 1
                state.target_found[k, t] = True
                state.found_grid[k, r + h, c + h] = True
                state.n_found[k] += 1
                break
    return credited


def _sense(config: WorldConfig, state: WorldState, k: int) -> tuple[list[float], list[float]]:
    """SPEC step 3, eq. 1-2 of the paper: Δp = λkΓp per footprint, several footprints on one cell combined as
    a product of survivals, and what the cell lost split among the agents in proportion to their c·Γ.
    Returns (M_p, M_u) per agent, eq. 3-4."""
    c = config.lam * (config.k + config.k_per_n * int(state.size[k]))  # k related to the world's side n
    h = state.halo
    covers: dict[tuple[int, int], list[tuple[int, float]]] = {}  # padded cell -> [(agent, f_i)] by index
    for i in range(state.n_agents):
        row, col = int(state.pos[k, i, 0]), int(state.pos[k, i, 1])
        for dr in range(-2, 3):
            for dc in range(-2, 3):
                g = float(GAMMA[dr + 2, dc + 2])
                if g > 0:
                    covers.setdefault((row + dr + h, col + dc + h), []).append((i, c * g))
    m_p = [0.0] * state.n_agents
    m_u = [0.0] * state.n_agents
    for (pr, pc), agents in covers.items():
        survive = 1.0
        for _, f in agents:
            survive *= 1.0 - f
        f_total = sum(f for _, f in agents)
        for true_map, credit in ((state.p, m_p), (state.u, m_u)):
            old = float(true_map[k, pr, pc])
            new = np.float32(old * survive)
            removed = old - float(new)
            true_map[k, pr, pc] = new
            for i, f in agents:
                credit[i] += removed * f / f_total
    return m_p, m_u


def _sweep(state: WorldState, k: int) -> list[bool]:
    """SPEC step 3, *Swept*: per agent, whether its footprint held no free cell the team had not swept before
    this step; then the footprints are swept."""
    h = state.halo
    cells = [
        {
            (int(state.pos[k, i, 0]) + dr + h, int(state.pos[k, i, 1]) + dc + h)
            for dr in range(-2, 3)
            for dc in range(-2, 3)
            if GAMMA[dr + 2, dc + 2] > 0
        }
        for i in range(state.n_agents)
    ]
    stale = [all(state.swept[k, r, c] or state.blocked[k, r, c] for r, c in mine) for mine in cells]
    for mine in cells:
        for r, c in mine:
            state.swept[k, r, c] = True
    return stale


def _refresh_beliefs(config: WorldConfig, state: WorldState, k: int) -> None:
    """SPEC step 4: the explicit area Φ of §3.2.1 shows the true maps."""
    r_phi, h = config.explicit_area // 2, state.halo
    for i in range(state.n_agents):
        row, col = int(state.pos[k, i, 0]) + h, int(state.pos[k, i, 1]) + h
        for pr in range(row - r_phi, row + r_phi + 1):
            for pc in range(col - r_phi, col + r_phi + 1):
                state.belief[k, i, 0, pr, pc] = state.p[k, pr, pc]
                state.belief[k, i, 1, pr, pc] = state.u[k, pr, pc]
                if config.belief_age > 0:  # seen at the step count this step ends with
                    state.belief_time[k, i, pr, pc] = state.t[k] + 1


def _see_neighbours(config: WorldConfig, state: WorldState, k: int) -> None:
    """SPEC step 4b (belief_seen): each other agent in the field of view scales belief_seen under its footprint
    by (1 − Γ); then the agent's own Φ is set back to 1."""
    r_f, r_phi, h = config.fov // 2, config.explicit_area // 2, state.halo
    for i in range(state.n_agents):
        row, col = int(state.pos[k, i, 0]) + h, int(state.pos[k, i, 1]) + h
        for j in range(state.n_agents):
            jr, jc = int(state.pos[k, j, 0]) + h, int(state.pos[k, j, 1]) + h
            if j == i or abs(jr - row) > r_f or abs(jc - col) > r_f:
                continue
            for dr in range(-2, 3):
                for dc in range(-2, 3):
                    state.belief_seen[k, i, jr + dr, jc + dc] *= 1.0 - float(GAMMA[dr + 2, dc + 2])
        state.belief_seen[k, i, row - r_phi : row + r_phi + 1, col - r_phi : col + r_phi + 1] = 1.0


def _neighbours(config: WorldConfig, state: WorldState, k: int) -> list[list[int]]:
    """Agents within the square communication area (§5.1) of each agent, Chebyshev distance <= r_C."""
    r_c = config.comm_range // 2
    out: list[list[int]] = [[] for _ in range(state.n_agents)]
    for i in range(state.n_agents):
        for j in range(state.n_agents):
            d = np.abs(state.pos[k, i] - state.pos[k, j]).max()
            if i != j and d <= r_c:
                out[i].append(j)
    return out


def _communicate(config: WorldConfig, state: WorldState, k: int) -> tuple[int, list[float], list[float]]:
    """SPEC step 5: min-merge of eq. 13-14 with direct neighbours, gains ΔM of eq. 15-16.
    Returns (unordered neighbour pairs, ΔM_p per agent, ΔM_u per agent)."""
    neighbours = _neighbours(config, state, k)
    pairs = sum(len(js) for js in neighbours) // 2
    gain_p = [0.0] * state.n_agents
    gain_u = [0.0] * state.n_agents
    if not config.communication:
        return pairs, gain_p, gain_u
    before = state.belief[k].copy()  # simultaneous: everyone merges the post-refresh beliefs
    for i in range(state.n_agents):
        if not neighbours[i]:
            continue
        merged = before[i].copy()
        for j in neighbours[i]:
            merged = np.minimum(merged, before[j])
        gain_p[i] = float((before[i, 0].astype(np.float64) - merged[0].astype(np.float64)).sum())
        gain_u[i] = float((before[i, 1].astype(np.float64) - merged[1].astype(np.float64)).sum())
        state.belief[k, i] = merged
    return pairs, gain_p, gain_u


def oracle_step(config: WorldConfig, state: WorldState, actions: np.ndarray, rng: np.random.Generator) -> OracleResult:
    """One step of every world, SPEC steps 1-7, in place on `state`. Rewards follow Table 1 with R_in of
    eq. 5 and R_comm of eq. 17."""
    n_worlds, n_agents = state.n_worlds, state.n_agents
    actions = np.asarray(actions)
    priority = rng.random((n_worlds, n_agents))  # the only random draws, in this order
    detect = rng.random((n_worlds, state.target_valid.shape[1]))
    res = OracleResult(
        reward=np.zeros((n_worlds, n_agents), np.float32),
        terminated=np.zeros(n_worlds, bool),
        truncated=np.zeros(n_worlds, bool),
        collided=np.zeros((n_worlds, n_agents), bool),
        targets_found=np.zeros((n_worlds, n_agents), np.int64),
        info_collected=np.zeros((n_worlds, n_agents), np.float64),
        comm_gain=np.zeros((n_worlds, n_agents), np.float64),
        comm_pairs=np.zeros(n_worlds, np.int64),
    )
    for k in range(n_worlds):
        blocked = _move(state, k, actions, priority)
        credited = _detect(state, k, detect)
        m_p, m_u = _sense(config, state, k)
        stale = _sweep(state, k)
        _refresh_beliefs(config, state, k)
        if config.belief_seen:
            _see_neighbours(config, state, k)
        pairs, gain_p, gain_u = _communicate(config, state, k)
        team_return = 0.0
        for i in range(n_agents):
            r = (
                config.step_reward
                + config.collision_reward * blocked[i]
                + config.target_reward * credited[i]
                + (config.xi / config.lam) * (m_p[i] + m_u[i])
                + (config.tau / config.lam) * (gain_p[i] + gain_u[i])
            )
            team_return += r
            res.reward[k, i] = r
            res.collided[k, i] = blocked[i]
            res.targets_found[k, i] = credited[i]
            res.info_collected[k, i] = m_p[i] + m_u[i]
            res.comm_gain[k, i] = gain_p[i] + gain_u[i]
        res.comm_pairs[k] = pairs
        state.t[k] += 1
        res.terminated[k] = state.n_found[k] == state.n_targets[k]
        res.truncated[k] = state.t[k] >= config.max_steps and not res.terminated[k]
        state.ep_return[k] += team_return
        state.ep_info[k] += sum(m_p) + sum(m_u)
        state.ep_collisions[k] += sum(blocked)
        state.ep_stale[k] += sum(stale)
        state.ep_comm_pairs[k] += pairs
    return res


def oracle_observe(config: WorldConfig, state: WorldState) -> tuple[np.ndarray, np.ndarray]:
    """The FOV window Θ (five channels, six with belief_age_channel) and the 3-vector of §3.2.1, per SPEC
    "Observation"."""
    n_worlds, n_agents, fov, h = state.n_worlds, state.n_agents, config.fov, state.halo
    r_f = fov // 2
    maps = np.zeros((n_worlds, n_agents, 6 if config.belief_age_channel else 5, fov, fov), np.float32)
    vector = np.zeros((n_worlds, n_agents, 3), np.float32)
    for k in range(n_worlds):
        n = int(state.size[k])
        for i in range(n_agents):
            row, col = int(state.pos[k, i, 0]), int(state.pos[k, i, 1])
            for j in range(n_agents):
                dr, dc = int(state.pos[k, j, 0]) - row, int(state.pos[k, j, 1]) - col
                if j != i and abs(dr) <= r_f and abs(dc) <= r_f:
                    maps[k, i, 0, dr + r_f, dc + r_f] = 1.0
            for wr in range(fov):
                for wc in range(fov):
                    pr, pc = row + h - r_f + wr, col + h - r_f + wc
                    maps[k, i, 1, wr, wc] = float(state.blocked[k, pr, pc])
                    maps[k, i, 2, wr, wc] = float(state.found_grid[k, pr, pc])
                    fresh = 1.0
                    if config.belief_age > 0:  # SPEC "Observation": ρ = N·ΣΓ / free cells of world k
                        free = int((~state.blocked[k]).sum())
                        rate = config.belief_age * n_agents * float(GAMMA.sum()) / free
                        fresh = np.exp(-rate * (int(state.t[k]) - int(state.belief_time[k, i, pr, pc])))
                        if config.belief_seen:  # what the neighbours it saw have sensed
                            fresh *= float(state.belief_seen[k, i, pr, pc])
                    if config.belief_age_channel:  # shown on its own; the belief keeps its scale
                        maps[k, i, 5, wr, wc], fresh = fresh, 1.0
                    maps[k, i, 3, wr, wc] = state.belief[k, i, 0, pr, pc] * state.obs_scale[k, 0] * fresh
                    maps[k, i, 4, wr, wc] = state.belief[k, i, 1, pr, pc] * state.obs_scale[k, 1] * fresh
            remaining = int(state.n_targets[k] - state.n_found[k])
            vector[k, i] = (col / n, row / n, remaining / int(state.n_targets[k]))
    return maps, vector
