"""The objects a run is built from its Plan (searchrl/train/plan.py): VecEnv, teacher labels, SB3 algorithm."""

from __future__ import annotations

from dataclasses import asdict

from omegaconf import DictConfig
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecEnv

from searchrl.envs.rewards import make_reward
from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.policies.checkpoint import load_checkpoint, policy_class, run_config
from searchrl.policies.networks import observation_parts, policy_kwargs
from searchrl.train.plan import Plan
from searchrl.train.teacher_labels import TeacherLabels
from searchrl.train.teacher_term import TeacherTerm


def make_vec_env(plan: Plan, seed: int | None = None) -> VecEnv:
    """One SearchVecEnv, or a TeamMixVecEnv when env.extra_teams adds groups (group j seeded with seed + j); with
    the teacher term, wrapped to label every step with the teacher's action (`TeacherLabels`)."""
    parts = observation_parts(asdict(plan.settings.network), asdict(plan.settings.critic))
    reward = make_reward(plan.settings.reward)
    envs = [
        SearchVecEnv(
            world,
            n_worlds=k,
            seed=None if seed is None else seed + j,
            scenario=plan.scenario,
            parts=parts,
            reward=reward,
        )
        for j, (world, k) in enumerate(plan.groups)
    ]
    env = envs[0] if len(envs) == 1 else TeamMixVecEnv(envs)
    if plan.teacher_term and plan.teacher is not None:
        return TeacherLabels(env, plan.teacher, plan.teacher_args, plan.settings.seed)
    return env


def make_algorithm(plan: Plan, env: VecEnv) -> BaseAlgorithm:
    """A fresh algorithm on `env`, with the teacher term's settings and labels where the run uses them."""
    s = plan.settings
    algo = asdict(s.algo)
    algo.pop("name")
    network, critic = asdict(s.network), asdict(s.critic)  # the policies read a run's record: mappings
    model = plan.algorithm(
        policy_class(s.algo.name, critic),
        env,
        seed=s.seed,
        device=s.device,
        policy_kwargs=policy_kwargs(network, s.algo.name, critic),
        verbose=0,
        **algo,
    )
    attach_teacher(plan, model, env)
    return model


def load_algorithm(plan: Plan, path: str, env: VecEnv) -> BaseAlgorithm:
    """A checkpoint with its step count and optimiser state, attached to `env` (and its teacher labels); ValueError
    naming the file if it cannot be read."""
    model = load_checkpoint(path, plan.record(), cls=plan.algorithm, env=env, device=plan.settings.device)
    attach_teacher(plan, model, env)
    return model


def init_weights(model: BaseAlgorithm, path: str, cfg: DictConfig) -> list[str]:
    """Copy the policy weights of checkpoint `path` (read as `load_checkpoint` reads any file, by its own run's
    config, or by `cfg` for a file without one beside it) into the fresh `model` of a run configured by `cfg`; its
    optimiser state is not taken. Every tensor the
    two policies both have is copied and must have the same shape, and the actor's head must be among them, so a
    policy of another size or action set is refused (ValueError with the reason); the parts only `model` has (a
    whole-map branch, a critic of its own) keep their fresh weights. Returns the names of those parts."""
    try:
        try:
            own = run_config(path)
        except FileNotFoundError:  # a zip copied out of its run: read as this run's network
            own = cfg
        theirs = load_checkpoint(path, own, device="cpu").policy.state_dict()
    except ValueError as err:  # a zip of no run, a corrupt file: all end here
        raise ValueError(f"init={path!r} does not fit this run's policy: {err}") from None
    ours = model.policy.state_dict()
    shared = [name for name in ours if name in theirs]
    wrong = [name for name in shared if ours[name].shape != theirs[name].shape]
    if wrong or "action_net.weight" not in shared:
        why = (
            f"{wrong[0]} is {tuple(theirs[wrong[0]].shape)} there, {tuple(ours[wrong[0]].shape)} here"
            if wrong
            else "it has no actor head of this policy"
        )
        raise ValueError(
            f"init={path!r} does not fit this run's policy (algo, network, observation and action "
            f"spaces must match): {why}"
        )
    model.policy.load_state_dict({**ours, **{name: theirs[name] for name in shared}})
    # named_parameters names a module shared under two names (the actor's extractor) once
    fresh = [name for name, _ in model.policy.named_parameters() if name not in theirs]
    return sorted({".".join(name.split(".")[:2]) for name in fresh})


def attach_teacher(plan: Plan, model: BaseAlgorithm, env: VecEnv) -> None:
    """Give a teacher-term algorithm its settings and the wrapper's labels (None without a teacher)."""
    if isinstance(model, TeacherTerm):
        im = plan.settings.imitation
        source = env if isinstance(env, TeacherLabels) else None
        model.configure_teacher(im.rl_weight, im.rl_schedule, im.critic_warmup, source, im.rl_anneal_steps)
