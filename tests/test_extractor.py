"""The paper network (§4.2): six 3×3 convs, two max-pools, FC on the vector, two FC after concatenation."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from searchrl.envs.spaces import action_space, observation_space
from searchrl.policies.extractor import SearchCNN
from searchrl.world.config import WorldConfig


@pytest.mark.parametrize("fov", [11, 7])
def test_shape_and_layers(fov):
    space = observation_space(WorldConfig(fov=fov))
    net = SearchCNN(space, conv_channels=(8, 16, 32), vector_size=4, fc_sizes=(64, 48))
    convs = [m for m in net.conv if isinstance(m, nn.Conv2d)]
    assert len(convs) == 6 and all(c.kernel_size == (3, 3) for c in convs)
    assert sum(isinstance(m, nn.MaxPool2d) for m in net.conv) == 2
    assert sum(isinstance(m, nn.Linear) for m in net.head) == 2
    obs = {k: torch.as_tensor(v.sample()[None]).repeat(5, *([1] * len(v.shape))) for k, v in space.items()}
    out = net(obs)
    assert out.shape == (5, 48) and net.features_dim == 48


def test_gradients_reach_both_inputs():
    space = observation_space(WorldConfig())
    net = SearchCNN(space)
    obs = {"map": torch.rand(3, 5, 11, 11, requires_grad=True), "vector": torch.rand(3, 3, requires_grad=True)}
    net(obs).sum().backward()
    assert obs["map"].grad.abs().sum() > 0 and obs["vector"].grad.abs().sum() > 0


def test_action_space_size():
    assert action_space(WorldConfig()).n == 5 and action_space(WorldConfig(diagonal=True)).n == 9


@pytest.mark.parametrize(
    "kwargs, name",
    [({"conv_channels": (8, 16)}, "conv_channels"), ({"fc_sizes": ()}, "fc_sizes"), ({"vector_size": 0}, "vector")],
)
def test_bad_sizes_are_rejected(kwargs, name):
    with pytest.raises(ValueError, match=name):
        SearchCNN(observation_space(WorldConfig()), **kwargs)
