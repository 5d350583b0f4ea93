"""A trained SB3 policy as a batched controller, its recurrent state carried across steps."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import torch

from searchrl.policies.actor import Actor, sample_actions
from searchrl.policies.checkpoint import load_actor
from searchrl.world.coarse import reset_parts
from searchrl.world.config import WorldConfig
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams, random_source


class PolicyController:
    """Acts with a trained actor: actions sampled from the policy with its own generator (`seed`; world streams
    give each world its own), or argmax when `deterministic`. Each step draws one uniform per agent of every world,
    active or not, so a world's draws do not depend on which others are still running. The LSTM state of each of
    the K·N slots is carried across steps and zeroed where `reset` marks a new episode. Rows of worlds outside
    `active` are skipped (their actions are 0)."""

    def __init__(
        self, actor: Actor, config: WorldConfig, deterministic: bool = False, seed: int | WorldStreams = 0
    ) -> None:
        self.actor = actor
        self.config = config
        self.rng = None if deterministic else random_source(seed)
        self._state: torch.Tensor | None = None  # (2, layers, K·N, hidden) on the actor's device
        self._start = np.zeros(0, bool)  # (K·N,) slots whose next step begins an episode
        self._parts: dict[str, np.ndarray] = {}  # the actor's observation parts, (K, N, ...) each
        self._part_fns = tuple(copy.deepcopy(p) for p in actor.parts)  # its own: a part may remember an episode

    @classmethod
    def load(
        cls, path: str | Path, config: WorldConfig, deterministic: bool = False, seed: int = 0, device: str = "cpu"
    ) -> PolicyController:
        """Load `path` (a model.zip of a run) and act with it, its network on `device`."""
        return cls(load_actor(path, config, device=device), config, deterministic, seed)

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        slots = state.n_worlds * state.n_agents
        if self._start.shape[0] != slots:
            self._start = np.ones(slots, bool)
            self._state = self.actor.initial_state(slots)
        self._start |= np.repeat(np.asarray(mask, bool), state.n_agents)
        reset_parts(self._part_fns, state, self.config, np.flatnonzero(mask))

    def act(
        self, state: WorldState, maps: np.ndarray, vector: np.ndarray, active: np.ndarray | None = None
    ) -> np.ndarray:
        k, n = state.n_worlds, state.n_agents
        maps, vector = maps.reshape(k * n, *maps.shape[2:]), vector.reshape(k * n, -1)
        actions = np.zeros(k * n, np.int64)
        worlds = np.arange(k) if active is None else np.flatnonzero(active)
        parts = {}
        for part in self._part_fns:  # observed here: the episode runners observe the window and vector only
            if part.key not in self._parts or self._parts[part.key].shape[0] != k:
                self._parts[part.key] = np.zeros((k, *part.shape(self.config)), np.float32)
            part.fill(state, self.config, self._parts[part.key], worlds)
            parts[part.key] = self._parts[part.key].reshape(k * n, *self._parts[part.key].shape[2:])
        if active is None or active.all():
            rows = slice(None)
        else:
            rows = np.flatnonzero(np.repeat(active, n))
            maps, vector = maps[rows], vector[rows]
            parts = {key: values[rows] for key, values in parts.items()}
        lstm = None
        if self._state is not None:  # indexed on the device: the state never travels
            device = self._state.device
            slots = rows if isinstance(rows, slice) else torch.from_numpy(rows).to(device)
            keep = torch.from_numpy(~self._start[rows]).to(device)  # zero where an episode starts
            lstm = self._state[:, :, slots] * keep[None, None, :, None]
        logits, lstm = self.actor.logits(maps, vector, lstm, parts)
        if lstm is not None:
            self._state[:, :, slots] = lstm
        uniforms = None if self.rng is None else self.rng.random((k, n)).reshape(-1)[rows]
        actions[rows] = sample_actions(logits, uniforms)
        self._start[rows] = False
        return actions.reshape(k, n)
