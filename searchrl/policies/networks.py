"""Networks and critics by name: the features extractors a run's `network.extractor` and `critic.name` choose.

A network is an SB3 features extractor whose class says which observation keys it reads (`keys`) and which
observation parts the env must add for it (`parts`, searchrl/envs/parts.py). It registers itself here
(`register_network`, `register_critic`), and a recipe picks it by name:

- `search_cnn`: the paper's network (searchrl/policies/extractor.py), reading the window and the 3-vector.
- `own_map_cnn`: the paper's network plus a branch over the agent's whole belief map, coarse (`own_map`), added
  to its features through a gate that starts at 0 (ReZero): initialised from a clone of the paper's network, it
  acts as the clone until training opens the gate.
A network's own settings (and those of the parts it reads) are its constructor's typed keyword arguments
(searchrl/registry.py `settings_of`): `network=<name> network.<setting>=...` (searchrl/train/schema.py).

- critic `shared` (the default): the value head reads the actor's features, as in the paper.
- critic `true_state`: the critic has its own extractor, the paper's network plus a branch over the world's true
  state (`true_state`: the team's merged belief, the targets left, every agent, the time left), added to its
  features. Centralised training, decentralised execution: only the critic reads it, and only during training
  (an actor built from the policy never asks for it, searchrl/policies/actor.py).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from typing import Any, ClassVar

import torch
from gymnasium import spaces
from torch import nn

from searchrl.envs.parts import PARTS, make_parts, taken_settings
from searchrl.policies.extractor import SearchCNN
from searchrl.registry import Registry, settings_of
from searchrl.world.coarse import ObservationPart

NETWORKS: Registry[type[SearchCNN]] = Registry("network.extractor")
CRITICS: Registry[type[SearchCNN] | None] = Registry("critic.name", {"shared": None})


def register_network(name: str) -> Callable[[type[SearchCNN]], type[SearchCNN]]:
    """Decorator: register an actor's features extractor as `network.extractor=<name>`."""
    return NETWORKS.register(name)


def register_critic(name: str) -> Callable[[type[SearchCNN]], type[SearchCNN]]:
    """Decorator: register a critic's own features extractor as `critic.name=<name>`."""
    return CRITICS.register(name)


register_network("search_cnn")(SearchCNN)


def grid_encoder(channels: int, grid: int, width: int) -> nn.Sequential:
    """(B, channels, grid, grid) -> (B, width): three 3×3 convolutions (the last two of stride 2), a linear layer."""
    layers = nn.Sequential(
        nn.Conv2d(channels, 16, 3, padding=1),
        nn.ReLU(),
        nn.Conv2d(16, 32, 3, stride=2, padding=1),
        nn.ReLU(),
        nn.Conv2d(32, 32, 3, stride=2, padding=1),
        nn.ReLU(),
        nn.Flatten(),
    )
    with torch.no_grad():
        n_out = layers(torch.zeros(1, channels, grid, grid)).shape[1]
    return nn.Sequential(*layers, nn.Linear(n_out, width), nn.ReLU())


class WithGrid(SearchCNN):
    """The paper's network plus an encoder of one coarse observation part (`part`), added to its features."""

    part: ClassVar[str]
    gated: ClassVar[bool]

    def __init_subclass__(cls, **kwargs) -> None:
        if "part" in cls.__dict__:
            cls.parts = (cls.part,)
        super().__init_subclass__(**kwargs)

    def __init__(self, observation_space: spaces.Dict, **sizes: Any) -> None:
        """`sizes`: the paper network's (SearchCNN's conv_channels, vector_size, fc_sizes)."""
        super().__init__(observation_space, **sizes)
        if self.part not in observation_space.spaces:
            raise ValueError(f"the {type(self).__name__} network reads {self.part!r}, which the env does not observe")
        channels, grid, _ = observation_space[self.part].shape
        self.grid = grid_encoder(channels, grid, self.features_dim)
        # A gate, not a zero-initialised layer: SB3's orthogonal initialisation rewrites every linear layer.
        self.gate = nn.Parameter(torch.zeros(())) if self.gated else None

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        """observations: {"map", "vector", part: (B, C, G, G)} -> (B, features_dim)."""
        extra = self.grid(observations[self.part])
        return super().forward(observations) + (extra if self.gate is None else self.gate * extra)


@register_network("own_map_cnn")
class OwnMapCNN(WithGrid):
    """The paper's network plus the agent's own whole belief map, coarse, through a gate that starts at 0."""

    part = "own_map"
    gated = True


@register_critic("true_state")
class TrueStateCritic(WithGrid):
    """A critic's extractor: the paper's network plus the world's true state, coarse."""

    part = "true_state"
    gated = False


@dataclass
class NetworkConfig:
    """A run's `network` node: the actor's extractor by name and the paper network's widths; a registered network's
    own settings (and its parts') extend it (`network_schema`)."""

    extractor: str = "search_cnn"  # the actor's features extractor by name
    conv_channels: list[int] = field(default_factory=lambda: [32, 64, 128])  # three conv pairs
    vector_size: int = 32  # FC on the 3-vector
    fc_sizes: list[int] = field(default_factory=lambda: [256, 256])  # FC after concatenation
    lstm_hidden_size: int = 256  # recurrent algorithms only
    grid: int = 16  # side of the coarse whole-map view an extractor such as own_map_cnn reads


@dataclass
class CriticConfig:
    """A run's `critic` node; a registered critic's own settings extend it (`critic_schema`)."""

    name: str = "shared"  # shared: the value head on the actor's features; or a critic's own extractor by name
    grid: int = 16  # side of the coarse true-state view a critic such as true_state reads


def _parts_of(extractor: type | None) -> list:
    return [PARTS.lookup(name) for name in getattr(extractor, "parts", ())]


def network_schema(name: str) -> type[NetworkConfig]:
    """NetworkConfig extended by the settings of network `name` and of the observation parts it reads."""
    return NETWORKS.schema(name, NetworkConfig, "extractor", _parts_of(NETWORKS.lookup(name)))


def critic_schema(name: str) -> type[CriticConfig]:
    """CriticConfig extended by the settings of critic `name` and of the observation parts it reads."""
    return CRITICS.schema(name, CriticConfig, "name", _parts_of(CRITICS.lookup(name)))


def chosen(network: NetworkConfig, critic: CriticConfig | None) -> tuple[type[SearchCNN], type | None]:
    """(the actor's extractor class, the critic's or None for the shared one); ConfigError naming an unregistered
    choice."""
    return NETWORKS.lookup(network.extractor), CRITICS.lookup("shared" if critic is None else critic.name)


def critic_keys(network: NetworkConfig, critic: CriticConfig | None) -> dict[str, str]:
    """{part name: observation key} of the critic's parts that the actor reads with other settings (the actor's
    grid and the critic's): the env observes both, the actor's under the part's name (what a checkpoint's actor
    reads alone) and the critic's copy under `critic.<name>`."""
    actor, critic_cls = chosen(network, critic)
    if critic_cls is None:
        return {}
    actors = {name: taken_settings(name, asdict(network)) for name in getattr(actor, "parts", ())}
    return {
        name: f"critic.{name}"
        for name in getattr(critic_cls, "parts", ())
        if name in actors and taken_settings(name, asdict(critic)) != actors[name]
    }


def observation_parts(network: NetworkConfig, critic: CriticConfig | None) -> tuple[ObservationPart, ...]:
    """The observation parts the env must add for the actor's and the critic's extractors, each with the settings
    of its node that its class takes (`grid` and its own); a part both read with other settings is held twice
    (`critic_keys`)."""
    actor, critic_cls = chosen(network, critic)
    parts = make_parts((name, asdict(network)) for name in getattr(actor, "parts", ()))
    if critic_cls is None:
        return parts
    renamed, shared = critic_keys(network, critic), getattr(actor, "parts", ())
    own = make_parts((n, asdict(critic)) for n in getattr(critic_cls, "parts", ()) if n in renamed or n not in shared)
    for part in own:
        part.key = renamed.get(part.key, part.key)  # the critic's copy: the class's `key` names the actor's
    return parts + own


def own_settings(extractor: type, node: NetworkConfig | CriticConfig) -> dict[str, Any]:
    """The values in a `network` (or `critic`) node of the settings `extractor` itself takes (its typed keyword
    arguments), as keyword arguments of its constructor."""
    return {f.name: getattr(node, f.name) for f in fields(settings_of(extractor)) if hasattr(node, f.name)}


def policy_kwargs(network: NetworkConfig, algo: str, critic: CriticConfig | None = None) -> dict[str, Any]:
    """SB3 policy_kwargs of a run's `network` and `critic` settings for algorithm `algo`."""
    actor, critic_cls = chosen(network, critic)
    kwargs: dict[str, Any] = {
        "features_extractor_class": actor,
        "features_extractor_kwargs": {
            "conv_channels": list(network.conv_channels),
            "vector_size": network.vector_size,
            "fc_sizes": list(network.fc_sizes),
            **own_settings(actor, network),
        },
        "net_arch": [],  # policy and value heads are linear on the features (or the LSTM output), as in PRIMAL
    }
    if algo == "recurrent_ppo":
        kwargs["lstm_hidden_size"] = network.lstm_hidden_size
    if critic_cls is not None:
        kwargs["critic_extractor_class"] = critic_cls
        kwargs["critic_extractor_kwargs"] = own_settings(critic_cls, critic)
        if renamed := critic_keys(network, critic):
            kwargs["critic_keys"] = renamed
    return kwargs
