"""RGB pictures of a world in the paper's colours (Fig. 1, Fig. 4): red is probability, blue uncertainty,
white is no information left; agents purple, found targets brown, hidden targets green, obstacles black."""

from __future__ import annotations

import numpy as np

from searchrl.world.state import WorldState

AGENT = (128, 0, 160)
FOUND = (140, 80, 20)
HIDDEN = (0, 170, 0)
OBSTACLE = (0, 0, 0)


def map_image(p: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(n, n, 3) uint8 from p and u already scaled to [0, 1]: white minus red-ness for p, blue-ness for u."""
    p = np.clip(p, 0.0, 1.0)[..., None]
    u = np.clip(u, 0.0, 1.0)[..., None]
    shade = 255.0 - 200.0 * (p * np.array([0.0, 1.0, 1.0]) + u * np.array([1.0, 0.6, 0.0]))
    return np.clip(shade, 0, 255).astype(np.uint8)


def world_frame(state: WorldState, k: int, belief_of: int | None = None, cell: int = 4) -> np.ndarray:
    """Picture of world k, (n·cell, n·cell, 3) uint8: the true maps, or agent `belief_of`'s belief."""
    h, n = state.halo, int(state.size[k])
    inner = (slice(h, h + n), slice(h, h + n))
    if belief_of is None:
        p, u = state.p[k][inner], state.u[k][inner]
    else:
        p, u = state.belief[k, belief_of, 0][inner], state.belief[k, belief_of, 1][inner]
    img = map_image(p * state.obs_scale[k, 0], u * state.obs_scale[k, 1])
    img[state.blocked[k][inner]] = OBSTACLE
    valid = state.target_valid[k]
    tp, found = state.target_pos[k][valid], state.target_found[k][valid]
    img[tp[found, 0], tp[found, 1]] = FOUND
    img[tp[~found, 0], tp[~found, 1]] = HIDDEN
    img[state.pos[k, :, 0], state.pos[k, :, 1]] = AGENT
    return np.repeat(np.repeat(img, cell, axis=0), cell, axis=1)


def world_frames(state: WorldState, cell: int = 4) -> list[np.ndarray]:
    """One frame per world, padded with grey (not white, which means "no information") to the largest side."""
    frames = [world_frame(state, k, cell=cell) for k in range(state.n_worlds)]
    side = max(f.shape[0] for f in frames)
    out = []
    for f in frames:
        pad = side - f.shape[0]
        out.append(np.pad(f, ((0, pad), (0, pad), (0, 0)), constant_values=128))
    return out
