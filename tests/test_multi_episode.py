"""Per-episode state is reset: every rule with memory, played over several episodes in worlds that end at different
steps, plays each later episode exactly as the same episode started fresh in a world of its own.

`play_episodes` starts a world's next episode as soon as its own ends (`EpisodeQueue`), so with fewer worlds than
episodes a controller's memory of a world (a sweep plan, what it has seen, an evidence switch) must be reset at that
world's own end, mid-run, beside worlds still playing. With as many worlds as episodes, each episode starts fresh in
a world of its own at step 0: the reference. A memory kept past a world's end, or reset at another world's end,
changes a later episode. The planted missed resets below (each controller's `reset` applied to the world beside the
one whose episode ended) are caught by the same comparison.

The VecEnv's own auto-reset is held to the same: every array of a world whose episode ended mid-rollout equals that
world reset from the same generator in a fresh state (a planted reset that leaves one array as it was is caught,
for five of them).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from searchrl.controllers import registry
from searchrl.controllers.episodes import play_episodes
from searchrl.envs.team_mix import TeamMixVecEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.imitation.teacher_labels import TeacherLabels
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import PAPER, IidObstacles, Scenario

CONFIG = replace(WorldConfig(), world_size=(16, 16), n_agents=3, n_targets=(2, 2), n_distributions=(4, 4),
                 max_steps=48)  # fmt: skip
WALLS = Scenario(IidObstacles(0.2))
EPISODES = 6
# Each rule with its memory on: greedy's `seen` and `age`, the switch's evidence and reach weights among walls, the
# coverage and sweep plans
RULES = [("surfing", {}, PAPER), ("greedy", {"seen": True, "age": 0.5}, PAPER), ("greedy_target", {}, PAPER),
         ("coverage", {}, PAPER), ("switch", {"threshold": 1.0}, WALLS), ("path_greedy", {}, WALLS),
         ("sweep", {}, WALLS), ("random", {}, PAPER), ("rollout", {"horizon": 3}, PAPER)]  # fmt: skip


def _play(name: str, settings: dict, scenario: Scenario, slots: int | None) -> dict[str, np.ndarray]:
    seeds, keys = [900 + e for e in range(EPISODES)], [(3, 0, e, 0) for e in range(EPISODES)]
    factory = lambda config, streams: registry.make_controller(name, config, streams, settings)  # noqa: E731
    return play_episodes(factory, CONFIG, seeds, keys, scenario, slots=slots)


def _later_episodes_differ(name: str, settings: dict, scenario: Scenario, slots: tuple[int, ...] = (1, 3)) -> list[str]:
    """What differs between the episodes played in reused worlds (`slots` of them) and each played fresh."""
    fresh = _play(name, settings, scenario, None)
    assert len(set(fresh["L"].tolist())) > 1 and fresh["L"].min() < CONFIG.max_steps  # they end at different steps
    found = []
    for worlds in slots:
        reused = _play(name, settings, scenario, worlds)
        found += [f"{worlds} worlds: {metric}" for metric in fresh if not np.array_equal(reused[metric], fresh[metric])]
    return found


def test_rules_cover_every_registered_heuristic():
    assert {name for name, _, _ in RULES} == set(registry.HEURISTICS)


@pytest.mark.parametrize("name, settings, scenario", RULES, ids=[r[0] for r in RULES])
def test_each_later_episode_is_the_episode_started_fresh(name, settings, scenario):
    assert not _later_episodes_differ(name, settings, scenario)


def _reset_beside(cls: type):
    """`cls.reset` that, after the first, resets the world beside each one whose episode ended (np.roll of the
    mask) instead of it: the ended world keeps its memory, a playing one loses its own. (A reset skipped outright
    can leave a compiled kernel an index past its arrays, which crashes rather than fails.)"""
    original, calls = cls.reset, []

    def reset(self, state, mask):
        original(self, state, mask if not calls else np.roll(mask, 1))
        calls.append(mask)

    return reset


@pytest.mark.parametrize("name, settings, scenario", [r for r in RULES if r[0] in ("greedy", "coverage", "switch",
                                                                                    "path_greedy", "sweep")],
                         ids=lambda r: r if isinstance(r, str) else "")  # fmt: skip
def test_a_planted_missed_reset_is_caught(name, settings, scenario, monkeypatch):
    cls = registry.HEURISTICS[name].cls
    monkeypatch.setattr(cls, "reset", _reset_beside(cls))
    assert _later_episodes_differ(name, settings, scenario, slots=(3,))  # with one world the roll is no plant


# The VecEnv resets a world as soon as its episode ends, mid-rollout, beside worlds still playing.
AGED = replace(CONFIG, belief_age=0.5, belief_seen=True)  # every per-agent memory of the world kept


def _auto_resets(monkeypatch, config: WorldConfig, forget: str | None = None) -> list[tuple]:
    """Step a SearchVecEnv of 3 worlds with random moves until several episodes have ended; each auto-reset as
    (mask, the generator before it, the state after it). `forget`: an array the reset is made to leave as it was
    in the worlds it resets (a planted missed reset)."""
    import copy

    import searchrl.world.engine as engine

    resets, original = [], engine.reset_worlds

    def recording(config, state, mask, rng, scenario=PAPER):
        before, kept = copy.deepcopy(rng), getattr(state, forget).copy() if forget else None
        original(config, state, mask, rng, scenario)
        if forget:
            getattr(state, forget)[mask] = kept[mask]
        resets.append((mask.copy(), before, state.copy()))

    monkeypatch.setattr(engine, "reset_worlds", recording)
    env, rng = SearchVecEnv(config, n_worlds=3, seed=5), np.random.default_rng(0)
    env.reset()
    for _ in range(3 * config.max_steps):
        env.step(rng.integers(0, config.n_actions, env.num_envs))
    return resets[1:]  # the auto-resets (the first is env.reset's, of every world)


def _leftovers(resets: list[tuple], config: WorldConfig) -> list[str]:
    """The arrays of reset worlds that differ from the same worlds reset from the same generator in a fresh state."""
    from dataclasses import fields

    from searchrl.world.reset import reset_worlds
    from searchrl.world.state import allocate

    found = set()
    for mask, rng, after in resets:
        fresh = allocate(config, 3)
        reset_worlds(config, fresh, mask, rng)
        found |= {f.name for f in fields(after) if isinstance(getattr(after, f.name), np.ndarray)
                  and not np.array_equal(getattr(after, f.name)[mask], getattr(fresh, f.name)[mask])}  # fmt: skip
    return sorted(found)


def test_the_vec_env_resets_every_array_of_a_world_whose_episode_ended(monkeypatch):
    resets = _auto_resets(monkeypatch, AGED)
    assert sum(not m.all() for m, _, _ in resets) >= 2  # worlds ended apart from the others, mid-rollout
    assert _leftovers(resets, AGED) == []


@pytest.mark.parametrize("array", ["swept", "belief_time", "belief_seen", "ep_stale", "target_found"])
def test_a_planted_missed_reset_of_the_world_is_caught(monkeypatch, array):
    assert _leftovers(_auto_resets(monkeypatch, AGED, forget=array), AGED) == [array]


def _labels_without_teacher_resets(self):
    """TeacherLabels.step_wait with its teachers' resets left out: a planted missed reset."""
    obs, rewards, dones, infos = self.venv.step_wait()
    self._current = self._label(obs)
    return obs, rewards, dones, infos


@pytest.mark.parametrize("planted", [False, True])
def test_the_teachers_memory_is_reset_exactly_in_the_worlds_whose_episode_ended(planted, monkeypatch):
    """TeacherLabels over a team mix (two groups of worlds, slots of 3 and 2 agents): after every step each group's
    teacher is reset in the worlds of that group the VecEnv restarted, and only there; every array the teacher
    keeps per world then equals a fresh teacher's reset on the same state and acting once (the label)."""
    if planted:
        monkeypatch.setattr(TeacherLabels, "step_wait", _labels_without_teacher_resets)
        with pytest.raises(AssertionError):
            _check_teacher_resets()
    else:
        _check_teacher_resets()


def _check_teacher_resets() -> None:
    groups = [SearchVecEnv(AGED, n_worlds=3, seed=1), SearchVecEnv(replace(AGED, n_agents=2), n_worlds=2, seed=2)]
    env = TeacherLabels(TeamMixVecEnv(groups), registry.teacher_settings("greedy", {"seen": True, "age": 0.5}), seed=0)
    calls: list[list] = [[] for _ in groups]
    for j, teacher in enumerate(env.teachers):
        original = teacher.reset
        teacher.reset = lambda state, mask, j=j, original=original: (calls[j].append(mask.copy()),
                                                                     original(state, mask))  # fmt: skip
    env.reset()
    rng, restarted = np.random.default_rng(0), 0
    for _ in range(2 * AGED.max_steps):
        obs, _, dones, _ = env.step(rng.integers(0, AGED.n_actions, env.num_envs))
        for j, group in enumerate(groups):
            lo = int(env._bounds[j])
            ended = np.array([bool(dones[lo + k * group.n_agents]) for k in range(group.world.n_worlds)])
            assert np.array_equal(calls[j][-1], ended) if ended.any() else len(calls[j]) >= 1
            if ended.any() and not ended.all():
                restarted += 1
                fresh = registry.make_teacher(
                    registry.teacher_settings("greedy", {"seen": True, "age": 0.5}), group.config, 0
                )
                k, n, state = group.world.n_worlds, group.n_agents, group.world.state
                fresh.reset(state, np.ones(k, bool))
                part = slice(lo, lo + k * n)  # its labels' act: what the wrapper's teacher did since its reset
                fresh.act(
                    state, obs["map"][part].reshape(k, n, *obs["map"].shape[1:]), obs["vector"][part].reshape(k, n, -1)
                )
                mine = env.teachers[j]
                for name, value in vars(mine).items():
                    if isinstance(value, np.ndarray) and value.ndim and value.shape[0] == group.world.n_worlds:
                        assert np.array_equal(value[ended], getattr(fresh, name)[ended]), name
            calls[j] = calls[j][-1:]
    assert restarted >= 2  # some worlds restarted while others played on


# Imitation's demonstrations: a round plays max_steps steps in every world, and a world whose episode ends restarts
# at once. Its teacher must be reset in exactly that world at exactly that step, and the next step marked as an
# episode start for the world's slots (the LSTM is zeroed there when cloning). Planted in `collect` by hand, each
# fails the first test below: the start marked at the ending step instead of the next, the teacher's reset dropped.
def _collect(monkeypatch, skip_partial: bool = False) -> tuple[list[np.ndarray], list[np.ndarray], object]:
    """(the teacher's reset masks, the worlds' done masks per step, the demonstrations) of a two-round collect by
    coverage (a rule with a plan per world); with `skip_partial` the teacher ignores resets of some worlds only."""
    from searchrl.imitation import clone as imitation

    cls, resets, dones = registry.HEURISTICS["coverage"].cls, [], []
    original = cls.reset

    def reset(self, state, mask):
        resets.append(np.asarray(mask, bool).copy())
        if not (skip_partial and not np.all(mask)):  # the plant: a world's end leaves the teacher's memory
            original(self, state, mask)

    class Recorded(imitation.SearchWorld):
        def step(self, actions):
            tr = super().step(actions)
            dones.append(tr.result.done.copy())
            return tr

    monkeypatch.setattr(cls, "reset", reset)
    monkeypatch.setattr(imitation, "SearchWorld", Recorded)
    demos = imitation.collect([(CONFIG, 3)], registry.teacher_settings("coverage"), episodes=2, gamma=0.99, seed=0)
    return resets, dones, demos


def test_demonstrations_reset_the_teacher_where_each_world_ends_and_mark_the_next_step(monkeypatch):
    resets, dones, demos = _collect(monkeypatch)
    steps = CONFIG.max_steps
    expected = []
    for round_dones in (dones[:steps], dones[steps:]):
        expected.append(np.ones(3, bool))  # the round's start
        expected += [d for d in round_dones if d.any()]  # each step where some world ended, exactly those worlds
    assert len(resets) == len(expected) and all(np.array_equal(a, b) for a, b in zip(resets, expected, strict=True))
    assert sum(int(d.sum()) for d in dones) >= 4  # worlds ended inside rounds, at different steps
    starts = demos.starts.reshape(2, 3, CONFIG.n_agents, steps)  # (round, world, agent, step): group-major order
    for r in range(2):
        ended = np.stack(dones[r * steps : (r + 1) * steps])  # (steps, worlds)
        for k in range(3):
            after = np.broadcast_to(ended[:-1, k], (CONFIG.n_agents, steps - 1))  # an end at t: a start at t + 1
            np.testing.assert_array_equal(starts[r, k, :, 1:], after)
            assert not starts[r, k, :, 0].any()  # the round's first step: the LSTM starts from zeros anyway


def test_a_planted_missed_teacher_reset_changes_the_demonstrations(monkeypatch):
    _, _, clean = _collect(monkeypatch)
    monkeypatch.undo()
    _, _, planted = _collect(monkeypatch, skip_partial=True)
    assert not np.array_equal(clean.actions, planted.actions)  # the plant is seen in what the clone would learn


class StepsSinceReset:
    """A probe observation part with memory: per world, the fills since its last `reset` (its episode's steps + 1
    when the world calls `reset` exactly at each episode start and `fill` once after it and after each step)."""

    key, privileged, high = "since_reset", False, float("inf")

    def __init__(self) -> None:
        self.fills = np.zeros(0, np.int64)

    def shape(self, config: WorldConfig) -> tuple[int, ...]:
        return (config.n_agents, 1)

    def reset(self, state, config: WorldConfig, worlds: np.ndarray) -> None:
        if self.fills.shape != (state.n_worlds,):
            self.fills = np.zeros(state.n_worlds, np.int64)
        self.fills[worlds] = 0

    def fill(self, state, config: WorldConfig, out: np.ndarray, worlds: np.ndarray) -> None:
        self.fills[worlds] += 1
        out[worlds] = self.fills[worlds, None, None]


def _part_memory_errors(steps: int = 3 * CONFIG.max_steps) -> list[str]:
    """Step two SearchVecEnvs given one probe part with random moves: each must hold its own copy, and in every
    observation (terminal ones too) a world's probe must read its episode's step + 1."""
    part, rng, errors = StepsSinceReset(), np.random.default_rng(1), []
    envs = [SearchVecEnv(CONFIG, n_worlds=3, seed=s, parts=(part,)) for s in (4, 5)]
    if envs[0].world.part_fns[0] is envs[1].world.part_fns[0] or envs[0].world.part_fns[0] is part:
        errors.append("the envs share the part they were given")
    for env in envs:
        obs = env.reset()
        for step in range(steps):
            t = np.repeat(env.world.state.t, CONFIG.n_agents)
            if not np.array_equal(obs["since_reset"][:, 0], t + 1):
                errors.append(f"step {step}: {obs['since_reset'][:, 0].tolist()} against t + 1 {(t + 1).tolist()}")
            obs, _, _, infos = env.step(rng.integers(0, CONFIG.n_actions, env.num_envs))
            for slot, info in enumerate(infos):  # the episode ended at t + 1: its last observation reads t + 2
                if "terminal_observation" in info and info["terminal_observation"]["since_reset"][0] != t[slot] + 2:
                    errors.append(f"step {step}: slot {slot}'s terminal observation reads its episode's start")
    return errors


def test_a_part_with_memory_is_reset_exactly_where_each_world_starts_an_episode():
    assert not _part_memory_errors()


@pytest.mark.parametrize("planted", ["auto_reset_skipped", "shared"])
def test_a_planted_missed_reset_of_a_part_is_caught(planted, monkeypatch):
    """Planted: the worlds' auto-resets skip the parts' reset (env.reset's of every world kept), or every world
    holds the one part it was given."""
    import copy

    import searchrl.world.engine as engine

    if planted == "shared":
        monkeypatch.setattr(copy, "deepcopy", lambda x, memo=None: x)
    else:
        original = engine.reset_parts

        def all_worlds_only(parts, state, config, worlds):
            if len(worlds) == state.n_worlds:
                original(parts, state, config, worlds)

        monkeypatch.setattr(engine, "reset_parts", all_worlds_only)
    assert _part_memory_errors()


def test_each_groups_teacher_draws_from_its_own_seed_and_a_rule_with_memory_labels_a_team_mix():
    """Group j's teacher is seeded with seed + j: the same seed labels the same random moves (greedy moves at random
    where nothing is left to sense, soon in worlds this small), another seed others. A rule with memory (the
    evidence switch, coverage's plan) is reset on each world's start as it is in evaluation."""
    tiny = replace(CONFIG, world_size=(6, 6), n_agents=2, n_targets=(1, 1), n_distributions=(1, 1), max_steps=40)

    def labels(teacher: str, args: dict, seed: int) -> np.ndarray:
        groups = [SearchVecEnv(tiny, 2, seed=1), SearchVecEnv(replace(tiny, n_agents=3), 1, seed=2)]
        env = TeacherLabels(TeamMixVecEnv(groups), registry.teacher_settings(teacher, args), seed=seed)
        env.reset()
        rng = np.random.default_rng(0)
        for _ in range(50):  # past the first episode's end
            env.step(rng.integers(0, 5, size=env.num_envs))
        return env.rollout_labels(50)

    same, other = labels("greedy_target", {}, 5), labels("greedy_target", {}, 6)
    np.testing.assert_array_equal(same, labels("greedy_target", {}, 5))
    assert (same != other).any()
    for rule, args in (("switch", {"threshold": 1.0}), ("coverage", {})):
        assert labels(rule, args, 0).shape == (50, 7)


def _slot_code(maps: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """(…,) an action of each slot's own observation: both its window and its 3-vector move it."""
    return (np.floor(maps[..., 0, :, :].sum(axis=(-1, -2)) * 7 + vector[..., 0] * 13) % 5).astype(np.int64)


class _Observer:
    """A rule that reads the observations (as a learned policy does), not the world state."""

    def __init__(self, config, seed=0) -> None:
        self.config = config

    def reset(self, state, mask) -> None:
        pass

    def act(self, state, maps, vector, active=None) -> np.ndarray:
        k, n = state.n_worlds, state.n_agents
        assert maps.shape == (k, n, 5, 11, 11) and vector.shape == (k, n, 3)  # per world, per agent
        return _slot_code(maps, vector).astype(np.int32)  # a rule may answer in any integer type


def test_a_teacher_reads_the_observations_of_its_own_slots():
    from dataclasses import dataclass

    from searchrl.controllers.base import ControllerConfig
    from tests.registries import isolated_registries

    @dataclass
    class ObserverConfig(ControllerConfig):
        name: str = "observer"

    with isolated_registries():
        registry.register("observer", _Observer, ObserverConfig)
        groups = [SearchVecEnv(CONFIG, 2, seed=1), SearchVecEnv(replace(CONFIG, n_agents=2), 3, seed=2)]
        env = TeacherLabels(TeamMixVecEnv(groups), registry.teacher_settings("observer"), seed=0)
        with pytest.raises(RuntimeError, match=r"^TeacherLabels: reset\(\) before the first step$"):
            env.step_async(np.zeros(env.num_envs, np.int64))
        obs, rng = env.reset(), np.random.default_rng(0)
        with pytest.raises(RuntimeError, match=r"^TeacherLabels holds 0 labelled steps, fewer than n_steps=1$"):
            env.rollout_labels(1)
        for _ in range(5):
            expected = _slot_code(obs["map"], obs["vector"])
            obs = env.step(rng.integers(0, 5, size=env.num_envs))[0]
            labels = env.rollout_labels(1)[0]
            assert labels.dtype == np.int64  # what the teacher term's cross-entropy indexes with
            np.testing.assert_array_equal(labels, expected)
