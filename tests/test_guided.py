"""analysis/guided_b.py, an experiment that plugs in through the extension points alone: its observation parts
point where path_greedy goes, each remembers its episode and forgets it where its world starts another (a planted
missed reset is caught), its networks act as the network they start from until their gates open, and its recipes
train and evaluate with `extensions=` and nothing else."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from searchrl.controllers.episodes import play_episodes
from searchrl.controllers.walls import PathGreedy
from searchrl.envs.parts import make_part, make_parts
from searchrl.envs.spaces import observation_space
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.policies.extractor import SearchCNN
from searchrl.world.coarse import reset_parts
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import PAPER, IidObstacles, Scenario
from tests.registries import isolated_registries

WALLS = Scenario(IidObstacles(0.3, connected=True))


@pytest.fixture(scope="module", autouse=True)
def guided():
    """analysis/guided_b.py, its parts, networks and teachers registered for this file's tests only."""
    with isolated_registries("analysis"):
        import analysis.guided_b

        yield analysis.guided_b


def test_the_guidance_points_where_path_greedy_goes():
    """On walled worlds, where path_greedy moves, the move is the best of the guidance's values (1.0) or its walk;
    a move blocked by an agent sends path_greedy to its second best, so nearly all, not all, agree. The env's own
    copy of the part follows its worlds through their resets, terminal observations included."""
    config = WorldConfig(world_size=(20, 30), n_agents=4, max_steps=12)
    env = SearchVecEnv(config, n_worlds=6, seed=3, scenario=WALLS, parts=make_parts([("guidance", {})]))
    rule, agree, moved, terminal = PathGreedy(config, seed=1), 0, 0, 0
    obs = env.reset()
    rule.reset(env.world.state, np.ones(6, bool))
    for _ in range(20):
        assert obs["guidance"].shape == (24, 8) and obs["vector"].shape == (24, 3)
        moves = rule.act(env.world.state, None, None).reshape(-1)
        values, walk = obs["guidance"][:, :4], obs["guidance"][:, 4:]
        for slot, a in enumerate(moves):
            if values[slot].max() > 0 or walk[slot].any():
                moved += 1
                agree += bool(values[slot, a - 1] == 1.0 or walk[slot, a - 1] == 1.0)
        obs, _, dones, infos = env.step(moves)
        rule.reset(env.world.state, dones.reshape(6, 4)[:, 0])
        terminal += sum(info["terminal_observation"]["guidance"].shape == (8,) for info in infos
                        if "terminal_observation" in info)  # fmt: skip
    assert moved > 200 and agree >= 0.9 * moved, (agree, moved)
    assert terminal == 24  # each world ended once (12 steps): its agents' last guidance


class PartMoves:
    """A controller that moves by one observation part's values alone (the best of its first A − 1, one per move,
    where one is positive, else a hash of them all), so whatever the part remembers shows in the episodes'
    metrics."""

    def __init__(self, name: str, config: WorldConfig) -> None:
        self.part, self.config = make_part(name), config

    def reset(self, state, mask: np.ndarray) -> None:
        reset_parts((self.part,), state, self.config, np.flatnonzero(mask))

    def act(self, state, maps, vector, active=None) -> np.ndarray:
        out = np.zeros((state.n_worlds, *self.part.shape(self.config)), np.float32)
        self.part.fill(state, self.config, out, np.arange(state.n_worlds) if active is None else np.flatnonzero(active))
        code = (out * np.arange(1, out.shape[2] + 1) * 997).sum(axis=2).astype(np.int64) + np.arange(state.n_agents)
        moves = out[:, :, : self.config.n_actions - 1]
        return np.where(moves.max(axis=2) > 0, 1 + moves.argmax(axis=2), 1 + code % (self.config.n_actions - 1))


CONFIG = replace(WorldConfig(), world_size=(12, 12), n_agents=3, n_targets=(2, 2), n_distributions=(4, 4),
                 max_steps=40)  # fmt: skip
PARTS = [("guidance", WALLS), ("evidence", PAPER), ("coverage_plan", PAPER)]


def _episodes(name: str, scenario: Scenario, slots: int | None) -> dict[str, np.ndarray]:
    episodes = 6
    seeds, keys = [700 + e for e in range(episodes)], [(5, 0, e, 0) for e in range(episodes)]
    return play_episodes(lambda config, streams: PartMoves(name, config), CONFIG, seeds, keys, scenario,
                         needs_observation=False, slots=slots)  # fmt: skip


def _later_episodes_differ(name: str, scenario: Scenario) -> list[str]:
    fresh, reused = _episodes(name, scenario, None), _episodes(name, scenario, 2)
    assert len(set(fresh["L"].tolist())) > 1  # the worlds end at different steps
    return [metric for metric in fresh if not np.array_equal(reused[metric], fresh[metric])]


@pytest.mark.parametrize("name, scenario", PARTS, ids=[p[0] for p in PARTS])
def test_each_part_plays_each_later_episode_as_the_episode_started_fresh(name, scenario):
    assert not _later_episodes_differ(name, scenario)


@pytest.mark.parametrize("name, scenario", PARTS, ids=[p[0] for p in PARTS])
def test_a_planted_missed_reset_of_a_part_is_caught(name, scenario, monkeypatch, guided):
    """Planted: the part's rule forgets the world beside each one whose episode ended (np.roll of the mask)."""
    original = guided._RulePart.reset

    def reset_beside(self, state, config, worlds):
        mask = np.zeros(state.n_worlds, bool)
        mask[worlds] = True
        original(self, state, config, np.flatnonzero(np.roll(mask, 1)) if mask.sum() < len(mask) else worlds)

    monkeypatch.setattr(guided._RulePart, "reset", reset_beside)
    assert _later_episodes_differ(name, scenario)


def test_a_guided_network_acts_as_the_network_it_starts_from_until_its_gates_open(guided):
    config = WorldConfig(world_size=(16, 16), n_agents=2)
    parts = make_parts([("guidance", {}), ("evidence", {}), ("coverage_plan", {})])
    space = observation_space(config, parts)
    source, net = SearchCNN(space), guided.GuidedPlanCNN(space)
    fresh = set(net.state_dict()) - set(source.state_dict())
    assert {name.split(".")[0] for name in fresh} == {"extra", "gates"}
    net.load_state_dict({**net.state_dict(), **source.state_dict()})
    obs = {key: torch.rand(5, *box.shape) for key, box in space.spaces.items()}
    assert torch.equal(net(obs), source(obs))
    with torch.no_grad():
        net.gates["evidence"].fill_(1.0)
    assert not torch.allclose(net(obs), source(obs))
