# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Guidance: path_greedy's view of every move, in the policy's observation (an experiment)
#
# `path_greedy` beats every shipped policy among walls because it reads the whole world: it walks shortest paths
# (BFS over the walls its prior shows) to the best cells within `radius` moves, and when that pocket is cleared,
# to the nearest worthwhile cell anywhere. The policy sees an 11×11 window. Here each agent's 3-vector gets
# 2·(A − 1) more numbers computed from what the agent holds (its belief, the walls, its position), with the rule's
# own machinery (searchrl/controllers/walls.py):
# - per move a: the best value, along a shortest path whose first move is a, of target-greedy's footprint
#   information within `radius` moves, discounted per move, divided by the best move's (0 where nothing is in reach);
# - per move a: 1 where the pocket in reach holds less than the rule's floor and a is the first move of the shortest
#   path to the nearest worthwhile cell of the whole world (the walk path_greedy would take), else 0.
#
# With GUIDED_EVIDENCE=1 (in training and evaluation alike) each agent also gets its world's evidence switch
# statistics (searchrl/controllers/switch.py: the team's finds against what the prior expected where it swept), and
# `walls_or_switch` is a teacher that follows the switch in open worlds: research/guided_b_evidence.
# With GUIDED_PLAN=1 (the evidence statistics too) each agent also gets the move coverage's team plan gives it, one-hot:
# the lane the switch would walk once it has turned, which an 11×11 window cannot show: research/guided_b_plan.
# `walls_or_oracle` is a privileged teacher for the same inputs: coverage from the start in an open world whose prior
# misleads (analysis/oracle_teacher.py), so the student learns how soon its evidence can tell: research/guided_b_oracle.
#
# The policy starts from a shipped one with the new inputs' weights at zero (so it acts exactly as that policy at
# first) and trains with the training app's recipe; validation and evaluation act through the same guided
# controller. Nothing here is in the library: the wrapper and the controller are patched into the apps.
#
#     python analysis/guided_b.py train +experiment=research/guided_walls_b threads=1      # then guided_walls_b_ppo
#     python analysis/guided_b.py evaluate suite=obstacles checkpoint=runs/train/guided/walls_b/model.zip \
#         out_dir=runs/suite/obstacles/policy/guided/walls_b

# %%
from __future__ import annotations

import os
import sys
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import torch
from numba import njit, prange
from stable_baselines3.common.vec_env import VecEnvWrapper

from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.coverage import GeometricCoverage
from searchrl.controllers.greedy_kernels import cell_information, view_scratch
from searchrl.controllers.policy import PolicyController
from searchrl.controllers.registry import make_controller, register
from searchrl.controllers.switch import MIN_EXPECTED, EvidenceSwitch, sweep_footprints
from searchrl.controllers.walls import PathGreedy, bfs, pocket_values
from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.policies.checkpoint import load_checkpoint
from searchrl.train.teacher_labels import TeacherLabels
from searchrl.world.config import WorldConfig
from searchrl.world.footprint import SUPPORT_DC, SUPPORT_DR, SUPPORT_G
from searchrl.world.parallel import chunk_count, chunk_span, world_threads
from searchrl.world.state import WorldState


# %%
@njit(parallel=True)  # not cached: a script's functions have no module to key a cache on
def guidance_values(w, params, memory, radius, floor, out, threads):
    """out (K, N, 2·(A − 1)) float32 <- the guidance of every agent (module text); agents shared among threads."""
    n_slots, side = out.shape[0] * out.shape[1], w.blocked.shape[1]
    n_chunks = chunk_count(n_slots, n_slots, threads)
    for chunk in prange(n_chunks):
        start, stop = chunk_span(chunk, n_chunks, 0, n_slots)
        _guidance_span(w, params, memory, radius, floor, out, start, stop, side)


@njit
def _guidance_span(w, params, memory, radius, floor, out, start, stop, side):
    dist, first = np.full((side, side), -1, np.int32), np.zeros((side, side), np.int64)
    queue = np.zeros((side * side, 2), np.int64)
    pos, h, n_actions = w.pos, w.halo, params.n_actions
    others = np.empty((1, 2), np.int64)
    best = np.zeros(n_actions)
    values = view_scratch(params)
    for slot in range(start, stop):
        k, i = slot // pos.shape[1], slot % pos.shape[1]
        r0, c0 = pos[k, i, 0] + h, pos[k, i, 1] + h
        pocket_values(w, params, memory, k, i, r0, c0, radius, dist, first, queue, best, others, values)
        top = best[1:].max()
        out[k, i, :] = 0.0
        for a in range(1, n_actions):
            out[k, i, a - 1] = best[a] / top if top > 0.0 else 0.0
        if top <= floor[k] * 13.0:  # the pocket is cleared: the first move towards the nearest worthwhile cell
            reached = bfs(w.blocked, k, r0, c0, np.int64(-1), n_actions, dist, first, queue)
            rate = memory.rates[k] if memory.known.shape[2] > 0 else 0.0
            for q in range(1, reached):
                r, c = queue[q, 0], queue[q, 1]
                info = cell_information(params, w.belief, w.p, memory.flat, w.obs_scale[k, 0], w.obs_scale[k, 1],
                                        memory.seen, memory.known, rate, w.t[k], k, i, r, c)  # fmt: skip
                if info > floor[k]:
                    out[k, i, n_actions - 1 + first[r, c] - 1] = 1.0
                    break
            for q in range(reached):
                dist[queue[q, 0], queue[q, 1]] = -1


PLAN = os.environ.get("GUIDED_PLAN") == "1"  # the fifth stage's coverage move (module text); with the evidence
EVIDENCE = PLAN or os.environ.get("GUIDED_EVIDENCE") == "1"  # the fourth stage's two more inputs (module text)


class Guide:
    """path_greedy's memory for a batch of worlds and the guidance it gives: `reset` where worlds restart,
    `values(state)` (K·N, 2·(A − 1)) float32; with EVIDENCE two more per agent, its world's evidence switch
    statistics (searchrl/controllers/switch.py): (found + 1) / (expected + 1) over 2, clipped to [0, 1], and the
    expected detections where the team swept over MIN_EXPECTED, clipped to [0, 1]; with PLAN, A − 1 more, one-hot,
    the move coverage's team plan gives the agent (its lane of the whole world; all 0 where it stays)."""

    def __init__(self, config: WorldConfig) -> None:
        self.rule = PathGreedy(config)
        self.plan = GeometricCoverage(config) if PLAN else None
        self.width = 2 * (config.n_actions - 1) + (2 if EVIDENCE else 0) + (config.n_actions - 1 if PLAN else 0)
        self.evidence = EvidenceSwitch(config) if EVIDENCE else None

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        self.rule.reset(state, mask)
        if self.evidence is not None:
            self.evidence.reset(state, mask)
        if self.plan is not None:
            self.plan.reset(state, mask)

    def values(self, state: WorldState) -> np.ndarray:
        out = np.zeros((state.n_worlds, state.n_agents, self.width), np.float32)
        rule = self.rule
        guidance_values(state.arrays(), rule._params, rule.remember(state), rule.radius, rule._floor, out,
                        world_threads())  # fmt: skip
        if self.evidence is not None:  # once per step: the team's footprints of this step, as the switch sweeps
            tracker = self.evidence
            if tracker.left.shape != state.p.shape:
                tracker.reset(state, np.ones(state.n_worlds, bool))
            sweep_footprints(state.pos, state.halo, tracker.left, SUPPORT_DR, SUPPORT_DC, SUPPORT_G)
            expected = state.n_targets * tracker.expected()
            first = 2 * (self.rule.config.n_actions - 1)
            out[:, :, first] = np.clip((state.n_found + 1.0) / (expected + 1.0) / 2.0, 0.0, 1.0)[:, None]
            out[:, :, first + 1] = np.clip(expected / MIN_EXPECTED, 0.0, 1.0)[:, None]
        if self.plan is not None:  # coverage's move, the stay (0) left out
            if self.plan.waypoints.shape[:2] != (state.n_worlds, state.n_agents):
                self.plan.reset(state, np.ones(state.n_worlds, bool))
            move = self.plan.act(state, None, None)
            first = self.width - (self.rule.config.n_actions - 1)
            for a in range(1, self.rule.config.n_actions):
                out[:, :, first + a - 1] = move == a
        return out.reshape(state.n_worlds * state.n_agents, self.width)


class Guidance(VecEnvWrapper):
    """A SearchVecEnv whose observation's vector carries the guidance after its 3 entries (zeros in a terminal
    observation: its world has restarted already)."""

    def __init__(self, venv: SearchVecEnv) -> None:
        self.guide = Guide(venv.config)
        space = venv.observation_space
        width = space["vector"].shape[0] + self.guide.width
        vector = gym.spaces.Box(-np.inf, np.inf, (width,), np.float32)
        super().__init__(venv, observation_space=gym.spaces.Dict({"map": space["map"], "vector": vector}))

    def reset(self):
        obs = self.venv.reset()
        self.guide.reset(self.venv.world.state, np.ones(self.venv.world.n_worlds, bool))
        return self._with(obs)

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        ended = dones.reshape(self.venv.world.n_worlds, -1)[:, 0]
        if ended.any():
            self.guide.reset(self.venv.world.state, ended)
        for info in infos:
            if "terminal_observation" in info:
                final = info["terminal_observation"]
                final["vector"] = np.concatenate([final["vector"], np.zeros(self.guide.width, np.float32)])
        return self._with(obs), rewards, dones, infos

    def _with(self, obs):
        return {"map": obs["map"], "vector": np.concatenate([obs["vector"], self.guide.values(self.venv.world.state)],
                                                            axis=1)}  # fmt: skip


class GuidedPolicyController(PolicyController):
    """PolicyController whose vector gets the guidance (validation and evaluation act through it)."""

    def __init__(self, actor, config: WorldConfig, deterministic: bool = False, seed=0) -> None:
        super().__init__(actor, config, deterministic, seed)
        self.guide = Guide(config)

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        super().reset(state, mask)
        self.guide.reset(state, mask)

    def act(self, state, maps, vector, active=None):
        guidance = self.guide.values(state).reshape(state.n_worlds, state.n_agents, -1)
        return super().act(state, maps, np.concatenate([vector, guidance], axis=2), active)


# %%
@dataclass
class WallsOrTargetConfig(ControllerConfig):
    name: str = "walls_or_target"


class WallsOrTarget:
    """A teacher chosen per world from what every agent holds (the walls its prior shows): path_greedy in a world
    with obstacles, B's teacher (target-greedy, reach 2) in an open one: the best rule of each family."""

    def __init__(self, config: WorldConfig, seed=0) -> None:
        self.walls = make_controller("path_greedy", config, seed=seed)
        self.open = make_controller("greedy_target", config, seed=seed, settings={"reach": 2})

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        self.walls.reset(state, mask)
        self.open.reset(state, mask)

    def act(self, state, maps, vector, active=None) -> np.ndarray:
        h = state.halo
        walled = np.array([state.blocked[k, h : h + n, h : h + n].any() for k, n in enumerate(state.size)])
        return np.where(walled[:, None], self.walls.act(state, maps, vector, active),
                        self.open.act(state, maps, vector, active))  # fmt: skip


class WallsOrSwitch(WallsOrTarget):
    """As WallsOrTarget, the evidence switch (threshold 0.25, tuned apart from the suites) in open worlds: B's teacher
    until the team finds under a quarter of what the prior expected where it swept, then coverage."""

    def __init__(self, config: WorldConfig, seed=0) -> None:
        self.walls = make_controller("path_greedy", config, seed=seed)
        self.open = make_controller("switch", config, seed=seed, settings={"threshold": 0.25})


@dataclass
class WallsOrSwitchConfig(ControllerConfig):
    name: str = "walls_or_switch"


class WallsOrOracle(WallsOrTarget):
    """As WallsOrTarget, a privileged teacher in open worlds (analysis/oracle_teacher.py's OracleSwitch, learning by
    cheating): B's teacher where the prior ranks the true targets above 0.25, coverage from the first step where it
    does not. The student sees only its evidence and coverage's move: it learns when its evidence says to turn."""

    def __init__(self, config: WorldConfig, seed=0) -> None:
        from oracle_teacher import OracleSwitch  # analysis/ is the script's folder: sys.path[0]

        self.walls = make_controller("path_greedy", config, seed=seed)
        self.open = OracleSwitch(config, threshold=0.25, seed=seed)


@dataclass
class WallsOrOracleConfig(ControllerConfig):
    name: str = "walls_or_oracle"


def make_guided_vec_env(plan, seed=None):
    """searchrl.train.build.make_vec_env with each group's worlds wrapped in `Guidance`."""
    envs = [Guidance(SearchVecEnv(world, n_worlds=k, seed=None if seed is None else seed + j, scenario=plan.scenario))
            for j, (world, k) in enumerate(plan.groups)]  # fmt: skip
    env = envs[0] if len(envs) == 1 else TeamMixVecEnv(envs)
    if plan.teacher_term and plan.teacher is not None:
        return TeacherLabels(env, str(plan.teacher), plan.teacher_args, int(plan.cfg.seed))
    return env


def widened_init(model, path: str, cfg=None) -> None:
    """init= from a policy without guidance: every weight copied, the vector layer's new input columns zero, so the
    policy first acts exactly as the one it starts from (read under its own run's config, as searchrl reads any)."""
    source = load_checkpoint(path, device="cpu").policy.state_dict()
    target = model.policy.state_dict()
    for key, value in source.items():
        if target[key].shape != value.shape:  # the vector's first layer: (out, 3) -> (out, 3 + guidance)
            widened = torch.zeros_like(target[key])
            widened[:, : value.shape[1]] = value
            value = widened
        target[key] = value
    model.policy.load_state_dict(target)


def patch_apps() -> None:
    import searchrl.controllers.factory as factory

    register("walls_or_target", WallsOrTarget, WallsOrTargetConfig)  # a teacher: imitation.teacher=walls_or_target
    register("walls_or_switch", WallsOrSwitch, WallsOrSwitchConfig)
    register("walls_or_oracle", WallsOrOracle, WallsOrOracleConfig)
    import searchrl.train.app as train_app

    train_app.make_vec_env = make_guided_vec_env
    train_app.init_weights = widened_init
    factory.POLICY_CONTROLLER = GuidedPolicyController  # validation, evaluation and render act through it


# %%
if __name__ == "__main__" and len(sys.argv) > 1 and sys.argv[1] in ("train", "evaluate"):
    import hydra

    from searchrl.paths import CONF_DIR

    app = sys.argv.pop(1)
    patch_apps()
    if app == "train":
        from searchrl.train.app import main
    else:
        from searchrl.evaluate.__main__ import main
    hydra.main(version_base="1.3", config_path=str(CONF_DIR), config_name=app)(main.__wrapped__)()
