"""searchrl/registry.py's rules, once for every kind of part: a name registered twice with the same part is
accepted, another part under a taken name is refused, a typo is refused in one line with the nearest name; and it
is the one registry implementation in the package."""

from __future__ import annotations

import re
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
import torch
from gymnasium import spaces

from searchrl.controllers.registry import HEURISTICS, Heuristic
from searchrl.envs.parts import PARTS
from searchrl.envs.rewards import REWARDS
from searchrl.policies.networks import CRITICS, NETWORKS
from searchrl.registry import Registry
from searchrl.world.config import ConfigError
from searchrl.world.scenario import PARTS as SCENARIO_PARTS

ROOT = Path(__file__).resolve().parents[1]
# (registry, a registered name, the setting its refusals name)
KINDS = [
    (NETWORKS, "search_cnn", "network.extractor"),
    (CRITICS, "true_state", "critic.name"),
    (PARTS, "own_map", "observation part"),
    (REWARDS, "paper", "reward"),
    (HEURISTICS, "greedy_target", "controller"),
    (SCENARIO_PARTS["obstacles"], "maze", "scenario.obstacles.kind"),
    (SCENARIO_PARTS["prior"], "misweighted", "scenario.prior.kind"),
    (SCENARIO_PARTS["targets"], "off_prior", "scenario.targets.kind"),
]
IDS = [setting for _, _, setting in KINDS]


def _another(part: object) -> object:
    """A part that is not `part`, of the same shape (a heuristic's entry, or a class with the same key)."""
    if isinstance(part, Heuristic):
        return Heuristic(part.cls, part.schema, "another")
    return type("Another", (part,), {})


@pytest.mark.parametrize(("registry", "name", "setting"), KINDS, ids=IDS)
def test_the_same_part_twice_is_accepted_and_another_under_its_name_refused(registry, name, setting):
    with mock.patch.dict(registry):
        part = registry[name]
        assert registry.register(name, part) is part and registry[name] is part
        with pytest.raises(ConfigError) as refused:
            registry.register(name, _another(part))
        assert str(refused.value).startswith(f"{setting}={name!r} cannot be registered: a new name is needed")
        assert "\n" not in str(refused.value) and registry[name] is part


@pytest.mark.parametrize(("registry", "name", "setting"), KINDS, ids=IDS)
def test_a_typo_is_refused_in_one_line_with_the_nearest_name(registry, name, setting):
    typo = name[:-1] + ("x" if name[-1] != "x" else "y")
    with pytest.raises(ConfigError) as refused:
        registry.lookup(typo)
    message = str(refused.value)
    assert message.startswith(f"{setting}={typo!r} is not allowed: one of {', '.join(registry)}")
    assert message.endswith(f"(did you mean {name!r}?)") and "\n" not in message
    assert registry.lookup(name) is registry[name]
    with pytest.raises(ConfigError, match=r"^imitation\.x=3 is not allowed"):
        registry.lookup(3, "imitation.x")  # not a name at all, under the setting a caller names


def test_a_registry_names_a_part_by_its_key_and_refuses_a_part_without_one():
    table: Registry[type] = Registry("scenario.toy.kind", key="kind")
    cls = table.register(part=type("Toy", (), {"kind": "toy"}))
    assert table == {"toy": cls}
    decorated = table.register("named")(type("Named", (), {}))
    assert table["named"] is decorated
    with pytest.raises(ConfigError, match=r"^scenario\.toy\.kind=None cannot be registered: a name is"):
        table.register(part=type("Nameless", (), {}))


def test_every_registry_is_one_registry_type():
    assert all(isinstance(registry, Registry) for registry, _, _ in KINDS)
    # no other module builds its own: refusing a taken name or a typo lives in searchrl/registry.py only
    own = [
        str(path.relative_to(ROOT))
        for path in (ROOT / "searchrl").rglob("*.py")
        if path.name != "registry.py" or path.parent.name != "searchrl"
        if re.search(r"registered already|is not registered|cannot be registered", path.read_text())
    ]
    assert own == []


def test_the_parts_listing_shows_every_registry_with_settings_and_a_users_parts(capsys):
    from searchrl.parts import main
    from tests.registries import isolated_registries

    with isolated_registries("tests.extension_example"):
        assert main(["extensions=[tests.extension_example.swept,tests.extension_example.eastward]"]) == 0
    out = capsys.readouterr().out
    headings = [line[:-1] for line in out.splitlines() if not line.startswith(" ")]
    assert headings == [registry.setting for registry, _, _ in KINDS]
    assert "  swept_cnn: tests.extension_example.swept.SweptCNN; settings: width=32" in out  # a user's parts
    assert "  eastward: tests.extension_example.eastward.Eastward; settings: margin=0" in out
    assert "  swept: tests.extension_example.swept.Swept; settings: scale=1.0" in out  # grid: network.grid
    assert "  switch: searchrl.controllers.switch.EvidenceSwitch; settings: threshold=0.5" in out
    assert "  maze: searchrl.world.obstacles.MazeObstacles; settings: corridor=3, loops=0.1" in out
    assert main(["extensions=[no_such_module]"]) == 2 and main(["seed=3"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and "'no_such_module' cannot be imported" in err[0] and err[1].startswith("error: seed=3")


def test_a_part_asked_for_by_the_actor_and_the_critic_with_two_settings_keeps_both():
    """The actor's and the critic's requests of one observation part: the same settings give one part; other
    settings give two, the critic's copy observed as `critic.<part>` and read by its extractor under the part's name
    (the actor's keeps the name a checkpoint's actor reads alone). One requester asking twice is refused."""
    from searchrl.envs.parts import make_parts
    from searchrl.envs.spaces import observation_space
    from searchrl.policies.checkpoint import policy_class
    from searchrl.policies.networks import CriticConfig, NetworkConfig, observation_parts, policy_kwargs
    from searchrl.world.config import WorldConfig
    from tests.registries import isolated_registries

    (part,) = make_parts([("own_map", {"grid": 8}), ("own_map", {"grid": 8, "unrelated": 1})])
    assert part.grid == 8
    with pytest.raises(ConfigError) as refused:
        make_parts([("own_map", {"grid": 16}), ("own_map", {"grid": 8})])
    assert "observation part 'own_map' is asked for with {'grid': 16} and with {'grid': 8}" in str(refused.value)
    assert "\n" not in str(refused.value)
    parts = observation_parts(NetworkConfig(extractor="own_map_cnn", grid=12), CriticConfig("true_state", grid=8))
    assert [(p.key, p.grid) for p in parts] == [("own_map", 12), ("true_state", 8)]  # two parts, each its own grid
    with isolated_registries("tests.extension_example"):
        import tests.extension_example.swept  # noqa: F401  (registers swept, swept_cnn, swept_critic)

        network, critic = NetworkConfig(extractor="swept_cnn", grid=8), CriticConfig(name="swept_critic", grid=4)
        network.width = 16  # the network's own setting (its schema's), absent from the base dataclass
        same = observation_parts(network, CriticConfig(name="swept_critic", grid=8))
        assert [(p.key, p.grid) for p in same] == [("swept", 8)]  # one part for both
        parts = observation_parts(network, critic)
        assert [(p.key, p.grid) for p in parts] == [("swept", 8), ("critic.swept", 4)]
        world = WorldConfig(n_agents=2, world_size=(12, 12), n_targets=(2, 2), n_distributions=(4, 4), max_steps=9)
        space = observation_space(world, parts)
        kwargs = policy_kwargs(network, "recurrent_ppo", critic)
        assert kwargs["critic_keys"] == {"swept": "critic.swept"}
        policy = policy_class("recurrent_ppo", critic)(space, spaces.Discrete(5), lambda _: 1e-3, **kwargs)
        obs = {k: torch.as_tensor(np.stack([space[k].sample() for _ in range(3)])) for k in space.spaces}
        seen = {}
        for name, extractor in (
            ("actor", policy.features_extractor),
            ("critic", policy.vf_features_extractor.extractor),
        ):
            extractor.register_forward_pre_hook(lambda _, args, name=name: seen.update({name: args[0]["swept"].shape}))
        policy.predict_values(obs, (torch.zeros(1, 3, 256),) * 2, torch.zeros(3))
        policy.get_distribution(obs, (torch.zeros(1, 3, 256),) * 2, torch.zeros(3))
        assert seen == {"actor": (3, 1, 8, 8), "critic": (3, 1, 4, 4)}  # each reads its own under the part's name
