"""The belief merge scans only what can change (searchrl/world/merge.py): a neighbour kept since the world's last
merge on its news, a new one on its box. Held bit for bit against the same engine scanning the whole union of the
neighbours' boxes at every step (a world that forgets its last merge, `merged` false, does that), on crowded teams
whose news passes along chains of neighbours."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.step import step
from tests.handmade import cfg, make_world

STEPS = 120


def _crowd(n: int, n_agents: int, **settings) -> WorldConfig:
    return replace(WorldConfig(), world_size=(n, n), n_targets=(2, 2), n_distributions=(3, 3), n_agents=n_agents,
                   communication=True, **settings)  # fmt: skip


@pytest.mark.parametrize(
    "config",
    [
        _crowd(16, 24),  # Φ 5×5, neighbours within 2 cells: many meet, part, and meet again
        _crowd(20, 30, explicit_area=3, comm_range=7),  # Φ smaller than the reach of a merge
        _crowd(14, 12, explicit_area=11, diagonal=True),  # Φ larger than the reach of a merge
    ],
)
def test_a_merge_that_scans_what_changed_equals_one_that_scans_every_neighbours_box(config: WorldConfig) -> None:
    world = SearchWorld(config, n_worlds=3, seed=5, auto_reset=False, observe=False)
    world.reset()
    whole = world.state.copy()  # the reference: forgets its last merge before every step
    actions = np.random.default_rng(6).integers(0, config.n_actions, size=(STEPS, 3, config.n_agents))
    kept_and_new = np.zeros(2, np.int64)
    for t in range(STEPS):
        last_merge = world.state.merge_pos.copy(), world.state.merged.copy()
        whole.merged[:] = False
        got = step(config, world.state, actions[t], np.random.default_rng(t))
        want = step(config, whole, actions[t], np.random.default_rng(t))
        assert np.array_equal(world.state.belief, whole.belief), f"beliefs differ after step {t}"
        assert np.array_equal(world.state.belief_box, whole.belief_box), f"boxes differ after step {t}"
        assert np.array_equal(got.comm_gain, want.comm_gain) and np.array_equal(got.reward, want.reward), t
        assert np.array_equal(world.state.ep_return, whole.ep_return)
        kept_and_new += _pairs(world.state.pos, *last_merge, config.comm_range // 2)
    assert world.state.merged.all() and (world.state.ep_comm_pairs > 0).all()
    assert kept_and_new.min() > 100, f"too few kept or new neighbours to test both: {kept_and_new}"


def _pairs(pos: np.ndarray, merge_pos: np.ndarray, merged: np.ndarray, radius: int) -> np.ndarray:
    """(kept, new): the ordered neighbour pairs at positions `pos` (K, N, 2) that were, or were not, neighbours at
    their world's last merge (`merge_pos`, `merged` as the step found them)."""
    kept = new = 0
    for k in range(pos.shape[0]):
        near = np.abs(pos[k, :, None] - pos[k, None]).max(-1) <= radius
        before = np.abs(merge_pos[k, :, None] - merge_pos[k, None]).max(-1) <= radius
        np.fill_diagonal(near, False)
        kept += int((near & before).sum()) if merged[k] else 0
        new += int((near & ~before).sum()) if merged[k] else int(near.sum())
    return np.array([kept, new])


def test_a_reset_forgets_the_last_merge_and_the_news() -> None:
    config = _crowd(16, 24)
    world = SearchWorld(config, n_worlds=2, seed=0, auto_reset=False, observe=False)
    world.reset()
    for t in range(5):
        world.step(np.random.default_rng(t).integers(0, config.n_actions, size=(2, config.n_agents)))
    assert world.state.merged.all()
    world.reset(mask=np.array([True, False]))
    side = world.state.p.shape[1]
    assert not world.state.merged[0] and world.state.merged[1]
    assert (world.state.belief_news[0] == (side, -1, side, -1)).all()


STAY, WEST = 0, 4


def test_news_passes_along_a_chain_of_kept_neighbours() -> None:
    """i and j stay neighbours while m, who has seen a far corner, comes within reach of j only: j learns the corner
    from m (a new neighbour: its whole box), then i from j (a kept one: j's news). Step by step the same as the
    whole union's scan; j's own Φ, refreshed every step, reaches i through its news too."""
    config = cfg(world_size=(40, 40), n_agents=3, communication=True, explicit_area=5, comm_range=5)
    i, j, m = 0, 1, 2
    state = make_world(config, 40, agents=[(20, 20), (20, 22), (20, 25)], targets=[(39, 39)], p=0.01, u=0.01)
    h, side = state.halo, state.p.shape[1]
    state.belief[0, m, 0, 5 + h, 5 + h] = 0.001  # what only m has seen
    state.belief[0, j, 0, 35 + h, 35 + h] = 0.002  # what only j has seen
    state.belief_box[0, [j, m]] = (0, side - 1, 0, side - 1)
    whole = state.copy()
    corner = (0, i, 0, 5 + h, 5 + h)
    for t, moves in enumerate([(STAY, STAY, STAY), (STAY, STAY, WEST), (STAY, STAY, STAY), (STAY, STAY, STAY)]):
        whole.merged[:] = False
        got = step(config, state, np.array([moves]), np.random.default_rng(t))
        want = step(config, whole, np.array([moves]), np.random.default_rng(t))
        assert np.array_equal(state.belief, whole.belief) and np.array_equal(got.comm_gain, want.comm_gain), t
        assert np.array_equal(state.belief_box, whole.belief_box), t
        assert state.merged[0]
        if t == 0:  # i and j meet: i learns j's far cell
            assert state.belief[0, i, 0, 35 + h, 35 + h] == np.float32(0.002)
        if t == 1:  # m meets j, not i
            assert state.belief[0, j, 0, 5 + h, 5 + h] == np.float32(0.001) and state.belief[corner] == np.float32(0.01)
    assert state.belief[corner] == np.float32(0.001)  # from j's news
