"""Per-episode state is reset: every rule with memory, played over several episodes in worlds that end at different
steps, plays each later episode exactly as the same episode started fresh in a world of its own.

`play_episodes` starts a world's next episode as soon as its own ends (`EpisodeQueue`), so with fewer worlds than
episodes a controller's memory of a world (a sweep plan, what it has seen, an evidence switch) must be reset at that
world's own end, mid-run, beside worlds still playing. With as many worlds as episodes, each episode starts fresh in
a world of its own at step 0: the reference. A memory kept past a world's end, or reset at another world's end,
changes a later episode. The planted missed resets below (each controller's `reset` applied to the world beside the
one whose episode ended) are caught by the same comparison.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from searchrl.controllers import registry
from searchrl.controllers.episodes import play_episodes
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
         ("sweep", {}, WALLS), ("random", {}, PAPER)]  # fmt: skip


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
