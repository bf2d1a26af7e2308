"""Feature extractors for stable-baselines3 policies on the package's observations.

stable-baselines3's default ``NatureCNN`` expects images of at least 36 x 36 pixels with uint8
values that it divides by 255. The belief image of ``ActiveLoc/Maze-v0`` is ``(5, n, n)``
float32 in [0, 1] with n = 7, 15 or 21, so it gets :class:`SmallCNN`, used with
``normalize_images=False``::

    policy_kwargs = dict(features_extractor_class=SmallCNN, normalize_images=False)
"""

from __future__ import annotations

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn


class SmallCNN(BaseFeaturesExtractor):
    """Three 3 x 3 convolutions (stride 1, padding 1: the spatial size is kept), then a
    linear layer.

    Args:
        observation_space: a ``Box`` of shape ``(C, H, W)`` (channels first), any size.
        features_dim: the size of the output feature vector.
        channels: the output channels of the convolutions, one per layer.
    """

    def __init__(
        self,
        observation_space: gym.spaces.Box,
        features_dim: int = 128,
        channels: tuple[int, ...] = (16, 32, 32),
    ) -> None:
        shape = observation_space.shape
        if shape is None or len(shape) != 3:
            raise ValueError(
                f"SmallCNN needs a (C, H, W) observation space, got shape {shape}"
            )
        if features_dim < 1 or not channels:
            raise ValueError(
                f"features_dim must be >= 1 and channels non-empty, got {features_dim}, "
                f"{channels}"
            )
        super().__init__(observation_space, features_dim)
        layers: list[nn.Module] = []
        in_channels = shape[0]
        for out_channels in channels:
            layers += [nn.Conv2d(in_channels, out_channels, 3, padding=1), nn.ReLU()]
            in_channels = out_channels
        self.cnn = nn.Sequential(*layers, nn.Flatten())
        n_flat = in_channels * shape[1] * shape[2]
        self.linear = nn.Sequential(nn.Linear(n_flat, features_dim), nn.ReLU())

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.linear(self.cnn(observations))


class PooledBeliefCNN(BaseFeaturesExtractor):
    """A fully convolutional extractor for belief images, pooled over space.

    The belief channels are divided by their per-sample maximum first: on a 15 x 15 maze the
    uniform prior is about 0.002 per pose, too small a signal for a freshly initialised network,
    while the belief's shape (which poses are still possible) is what the policy acts on. Then
    3 x 3 convolutions (stride 1, padding 1) see each cell's neighbourhood, and the mean and the
    maximum over all cells go to a linear layer. The weights are shared across the map, so the
    extractor works on any maze size and learns from every cell of every sample, where
    :class:`SmallCNN`'s flattened layer has to learn each position separately.

    Args:
        observation_space: a ``Box`` of shape ``(C, H, W)``, any ``H, W``.
        features_dim: the size of the output feature vector.
        channels: the output channels of the convolutions, one per layer.
        belief_channels: how many leading channels hold belief mass (4 headings in
            ``Maze-v0``); the rest (the map) pass unchanged. 0: no rescaling.
    """

    def __init__(
        self,
        observation_space: gym.spaces.Box,
        features_dim: int = 128,
        channels: tuple[int, ...] = (32, 64, 64),
        belief_channels: int = 4,
    ) -> None:
        shape = observation_space.shape
        if shape is None or len(shape) != 3:
            raise ValueError(
                f"PooledBeliefCNN needs a (C, H, W) observation space, got shape {shape}"
            )
        if features_dim < 1 or not channels or not 0 <= belief_channels <= shape[0]:
            raise ValueError(
                f"features_dim must be >= 1, channels non-empty and belief_channels in "
                f"[0, {shape[0]}], got {features_dim}, {channels}, {belief_channels}"
            )
        super().__init__(observation_space, features_dim)
        self.belief_channels = belief_channels
        layers: list[nn.Module] = []
        in_channels = shape[0]
        for out_channels in channels:
            layers += [nn.Conv2d(in_channels, out_channels, 3, padding=1), nn.ReLU()]
            in_channels = out_channels
        self.cnn = nn.Sequential(*layers)
        self.linear = nn.Sequential(nn.Linear(2 * in_channels, features_dim), nn.ReLU())

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        k = self.belief_channels
        if k:
            belief = observations[:, :k]
            peak = belief.amax(dim=(1, 2, 3), keepdim=True).clamp_min(1e-12)
            observations = torch.cat([belief / peak, observations[:, k:]], dim=1)
        maps = self.cnn(observations)  # (B, C, H, W)
        pooled = torch.cat([maps.mean(dim=(2, 3)), maps.amax(dim=(2, 3))], dim=1)
        return self.linear(pooled)
