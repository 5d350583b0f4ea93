"""The paper's network (§4.2, after PRIMAL) as an SB3 features extractor.

map (C, F, F) -> [conv3x3, conv3x3, maxpool] -> [conv3x3, conv3x3, maxpool] -> [conv3x3, conv3x3] -> flatten
vector (3,)   -> FC
concat        -> FC -> FC  = features (the LSTM of RecurrentPPO and the policy/value heads follow in SB3)

C = 5 channels, or 6 with belief_age_channel (searchrl/world/observe.py); F = fov, 11 by default.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from searchrl.world.config import ConfigError


def _conv_block(c_in: int, c_out: int, pool: bool) -> list[nn.Module]:
    layers: list[nn.Module] = [
        nn.Conv2d(c_in, c_out, 3, padding=1),
        nn.ReLU(),
        nn.Conv2d(c_out, c_out, 3, padding=1),
        nn.ReLU(),
    ]
    if pool:
        layers.append(nn.MaxPool2d(2))
    return layers


class SearchCNN(BaseFeaturesExtractor):
    """VGG-like extractor: six 3×3 convolutions in three pairs, max-pools after the first two pairs.

    observation_space: Dict {"map": (C, F, F), "vector": (V,)}. Output: (batch, fc_sizes[-1]).
    conv_channels: channels of the three conv pairs; vector_size: width of the FC on the vector;
    fc_sizes: widths of the FC layers after concatenation (the paper has two).
    """

    parts: tuple[str, ...] = ()  # the observation parts (searchrl/envs/parts.py) the env must add for it
    keys: tuple[str, ...] = ("map", "vector")  # the observation keys it reads: the window, the 3-vector, its parts

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        cls.keys = ("map", "vector", *cls.parts)

    def __init__(
        self,
        observation_space: spaces.Dict,
        conv_channels: Sequence[int] = (32, 64, 128),
        vector_size: int = 32,
        fc_sizes: Sequence[int] = (256, 256),
    ) -> None:
        c_in, fov, _ = observation_space["map"].shape
        self.check_sizes(conv_channels, vector_size, fc_sizes, fov)
        super().__init__(observation_space, features_dim=int(fc_sizes[-1]))
        c1, c2, c3 = conv_channels
        self.conv = nn.Sequential(
            *_conv_block(c_in, c1, pool=True),
            *_conv_block(c1, c2, pool=True),
            *_conv_block(c2, c3, pool=False),
            nn.Flatten(),
        )
        with torch.no_grad():
            n_conv = self.conv(torch.zeros(1, c_in, fov, fov)).shape[1]
        self.vector = nn.Sequential(nn.Linear(observation_space["vector"].shape[0], vector_size), nn.ReLU())
        width = n_conv + vector_size
        layers: list[nn.Module] = []
        for size in fc_sizes:
            layers += [nn.Linear(width, size), nn.ReLU()]
            width = size
        self.head = nn.Sequential(*layers)

    @staticmethod
    def check_sizes(conv_channels: Sequence[int], vector_size: int, fc_sizes: Sequence[int], fov: int = 11) -> None:
        """ValueError naming the bad size, before any network is built."""
        if fov < 5:
            raise ValueError(f"env.world.fov={fov!r} is too small for the network: two 2x2 max-pools need fov >= 5")
        if len(conv_channels) != 3 or min(conv_channels) < 1:
            raise ConfigError(f"network.conv_channels={list(conv_channels)!r} is not allowed: three positive counts")
        if vector_size < 1:
            raise ConfigError(f"network.vector_size={vector_size!r} is not allowed: must be >= 1")
        if not fc_sizes or min(fc_sizes) < 1:
            raise ConfigError(f"network.fc_sizes={list(fc_sizes)!r} is not allowed: one or more positive widths")

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        """observations: {"map": (B, C, F, F), "vector": (B, V)} -> (B, features_dim)."""
        # Channels-last convolutions: about 1.15x faster on CPU (mkldnn) than channels-first for these shapes
        maps = observations["map"].contiguous(memory_format=torch.channels_last)
        parts = [self.conv(maps), self.vector(observations["vector"])]
        return self.head(torch.cat(parts, dim=1))
