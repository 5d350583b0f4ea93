"""The objects a run is built from its Plan (searchrl/train/plan.py): VecEnv, teacher labels, SB3 algorithm."""

from __future__ import annotations

from omegaconf import DictConfig, OmegaConf
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecEnv

from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.policies.algorithms import ALGORITHMS
from searchrl.policies.checkpoint import load_checkpoint, policy_kwargs
from searchrl.train.plan import Plan
from searchrl.train.teacher_labels import TeacherLabels
from searchrl.train.teacher_term import TeacherTerm


def make_vec_env(plan: Plan, seed: int | None = None) -> VecEnv:
    """One SearchVecEnv, or a TeamMixVecEnv when env.extra_teams adds groups (group j seeded with seed + j); with
    the teacher term, wrapped to label every step with the teacher's action (`TeacherLabels`)."""
    envs = [SearchVecEnv(world, n_worlds=k, seed=None if seed is None else seed + j, scenario=plan.scenario)
            for j, (world, k) in enumerate(plan.groups)]  # fmt: skip
    env = envs[0] if len(envs) == 1 else TeamMixVecEnv(envs)
    if plan.teacher_term and plan.teacher is not None:
        return TeacherLabels(env, str(plan.teacher), plan.teacher_args, int(plan.cfg.seed))
    return env


def make_algorithm(plan: Plan, env: VecEnv) -> BaseAlgorithm:
    """A fresh algorithm on `env`, with the teacher term's settings and labels where the run uses them."""
    cfg = plan.cfg
    settings = OmegaConf.to_container(cfg.algo, resolve=True)
    settings.pop("name")
    model = plan.algorithm(ALGORITHMS[cfg.algo.name][1], env, seed=int(cfg.seed), device=cfg.device,
                           policy_kwargs=policy_kwargs(cfg.network, cfg.algo.name), verbose=0, **settings)  # fmt: skip
    attach_teacher(plan, model, env)
    return model


def load_algorithm(plan: Plan, path: str, env: VecEnv) -> BaseAlgorithm:
    """A checkpoint with its step count and optimiser state, attached to `env` (and its teacher labels); ValueError
    naming the file if it cannot be read."""
    model = load_checkpoint(path, plan.cfg, cls=plan.algorithm, env=env, device=plan.cfg.device)
    attach_teacher(plan, model, env)
    return model


def init_weights(model: BaseAlgorithm, path: str, cfg: DictConfig) -> None:
    """Copy the policy weights of checkpoint `path` into the fresh `model` of a run configured by `cfg` (its optimiser
    state is not taken), read as `load_checkpoint` reads any file: built from `cfg`, so weights of another network
    do not fit; ValueError with the reason if they do not fit."""
    try:
        params = load_checkpoint(path, cfg, device="cpu").get_parameters()
        model.set_parameters({"policy": params["policy"]}, exact_match=False, device=model.device)
    except Exception as err:  # a zip of another algorithm, a corrupt file, other shapes: all end here
        lines = str(err).strip().splitlines() or [type(err).__name__]
        more = f" (+{len(lines) - 1} more lines)" if len(lines) > 1 else ""
        raise ValueError(f"init={path!r} does not fit this run's policy (algo, network, observation and action "
                         f"spaces must match): {lines[0]}{more}") from None  # fmt: skip


def attach_teacher(plan: Plan, model: BaseAlgorithm, env: VecEnv) -> None:
    """Give a teacher-term algorithm its settings and the wrapper's labels (None without a teacher)."""
    if isinstance(model, TeacherTerm):
        im = plan.cfg.imitation
        source = env if isinstance(env, TeacherLabels) else None
        model.configure_teacher(float(im.rl_weight), str(im.rl_schedule), int(im.critic_warmup), source)
