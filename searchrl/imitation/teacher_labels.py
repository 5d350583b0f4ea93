"""`TeacherLabels`: a VecEnv wrapper that labels every observation the learner acts on with the teacher's action.

The teacher term of `searchrl/imitation/teacher_term.py` needs, for each step of each rollout, what the teacher would
have done in the state the learner was in (DAgger's labels, on the learner's own states). The heuristic teachers
read only the world state and the agents' observations, so they can label online: after every reset and step the
wrapper asks each group's teacher for its (K, N) actions, and when the learner acts (`step_async`) it files the
labels of the observation acted on. `rollout_labels(n_steps)` hands the algorithm the last rollout's labels,
(n_steps, n_envs), in the rollout buffer's layout. A world that ends restarts inside the VecEnv; its teacher is
reset there too (a coverage plan or greedy memory starts afresh). Labelling costs one teacher step per agent-step
(footprint-greedy: ~100k agent-steps/s, far above training's ~1k).
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env import VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.registry import make_teacher
from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv


class TeacherLabels(VecEnvWrapper):
    """Wraps a SearchVecEnv or TeamMixVecEnv; group j's teacher is seeded with `seed + j`."""

    def __init__(self, venv: SearchVecEnv | TeamMixVecEnv, teacher: ControllerConfig, seed: int) -> None:
        """`teacher`: a heuristic's settings (`registry.teacher_settings`)."""
        super().__init__(venv)
        self.groups: list[SearchVecEnv] = list(venv.envs) if isinstance(venv, TeamMixVecEnv) else [venv]
        self.teachers = [make_teacher(teacher, env.config, seed + j) for j, env in enumerate(self.groups)]
        self._bounds = np.cumsum([0] + [env.num_envs for env in self.groups])  # group j owns slots [b_j, b_j+1)
        self._current: np.ndarray | None = None  # (n_envs,) labels of the latest observation
        self._acted: list[np.ndarray] = []  # labels of each observation acted on since the last rollout_labels

    def reset(self) -> VecEnvObs:
        obs = self.venv.reset()
        for env, teacher in zip(self.groups, self.teachers, strict=True):
            teacher.reset(env.world.state, np.ones(env.world.n_worlds, bool))
        self._current = self._label(obs)
        self._acted.clear()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        if self._current is None:
            raise RuntimeError("TeacherLabels: reset() before the first step")
        self._acted.append(self._current)
        self.venv.step_async(actions)

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        for j, (env, teacher) in enumerate(zip(self.groups, self.teachers, strict=True)):
            ended = dones[self._bounds[j] : self._bounds[j + 1]].reshape(env.world.n_worlds, env.n_agents)[:, 0]
            if ended.any():  # those worlds were reset by the VecEnv
                teacher.reset(env.world.state, ended)
        self._current = self._label(obs)
        return obs, rewards, dones, infos

    def _label(self, obs: VecEnvObs) -> np.ndarray:
        """(n_envs,) int64: each group's teacher acting on its worlds' current state and observations."""
        parts = []
        for j, (env, teacher) in enumerate(zip(self.groups, self.teachers, strict=True)):
            lo, hi = self._bounds[j], self._bounds[j + 1]
            k, n = env.world.n_worlds, env.n_agents
            maps = obs["map"][lo:hi].reshape(k, n, *obs["map"].shape[1:])
            vector = obs["vector"][lo:hi].reshape(k, n, -1)
            parts.append(np.asarray(teacher.act(env.world.state, maps, vector), np.int64).reshape(-1))
        return np.concatenate(parts)

    def rollout_labels(self, n_steps: int) -> np.ndarray:
        """(n_steps, n_envs): the labels of the last `n_steps` observations acted on; the record then starts over."""
        if len(self._acted) < n_steps:
            raise RuntimeError(f"TeacherLabels holds {len(self._acted)} labelled steps, fewer than n_steps={n_steps}")
        labels = np.stack(self._acted[-n_steps:])
        self._acted.clear()
        return labels
