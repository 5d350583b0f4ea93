"""Episode metrics of §6.1.1, read from a state's accumulators (call before the world is reset)."""

from __future__ import annotations

import numpy as np

from searchrl.world.state import WorldState


def episode_metrics(state: WorldState) -> dict[str, np.ndarray]:
    """Per world (K,): search time L (steps taken; equals max_steps when targets remain), team return R,
    communication count F (neighbour pairs summed over steps), information collected per step M̄
    (team Σ(M_p + M_u) / L), found fraction, blocked moves, and stale agent-steps (no new cell swept)."""
    steps = np.maximum(state.t, 1)
    return {
        "L": state.t.copy(),
        "R": state.ep_return.copy(),
        "F": state.ep_comm_pairs.copy(),
        "M_bar": state.ep_info / steps,
        "found_fraction": state.n_found / np.maximum(state.n_targets, 1),
        "collisions": state.ep_collisions.copy(),
        "stale": state.ep_stale.copy(),
    }
