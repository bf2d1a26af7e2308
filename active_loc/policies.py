"""Feature extractors for stable-baselines3 policies on the package's observations.

stable-baselines3's default ``NatureCNN`` expects images of at least 36 x 36 pixels with uint8
values that it divides by 255. The belief image of ``ActiveLoc/Maze-v0`` is ``(5, n, n)``
float32 in [0, 1] with n = 7, 15 or 21, so it gets :class:`SmallCNN`, used with
``normalize_images=False``::

    policy_kwargs = dict(features_extractor_class=SmallCNN, normalize_images=False)

The ``Dict`` observation of the MCL and grid ids' ``observation="image"`` (the belief as an
image over the map, and the observation vector) gets :class:`BeliefImageExtractor` with
``MultiInputPolicy``.
"""

from __future__ import annotations

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn


def rescaled_belief(images: torch.Tensor, belief_channels: int) -> torch.Tensor:
    """Images ``(B, C, H, W)`` with their first ``belief_channels`` channels divided by their
    per-sample maximum (the others, the map, unchanged; 0: the images as they are)."""
    if not belief_channels:
        return images
    belief = images[:, :belief_channels]
    peak = belief.amax(dim=(1, 2, 3), keepdim=True).clamp_min(1e-12)
    return torch.cat([belief / peak, images[:, belief_channels:]], dim=1)


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
        maps = self.cnn(rescaled_belief(observations, self.belief_channels))  # (B, C, H, W)
        pooled = torch.cat([maps.mean(dim=(2, 3)), maps.amax(dim=(2, 3))], dim=1)
        return self.linear(pooled)


class BeliefImageExtractor(BaseFeaturesExtractor):
    """For the ``Dict`` observation of ``observation="image"``
    (:mod:`active_loc.envs.belief_image`): a CNN on the belief image beside an MLP layer on
    the observation vector, their features concatenated.

    The image's belief channels are divided by their per-sample maximum first (a belief
    spread over the map puts about 1e-4 in a cell, a converged one about 1). The map is laid
    out in the image, so where the mass lies matters: the convolutions (3 x 3, the second and
    third of stride 2) are pooled to a ``4 x 4`` grid and flattened, keeping the layout
    coarsely, not averaged away.

    Args:
        observation_space: a ``Dict`` with ``"image"`` ``(C, R, R)`` and ``"vector"`` ``(D,)``.
        features_dim: the size of the image's feature vector (the output adds
            ``vector_dim``).
        channels: the output channels of the convolutions, one per layer.
        vector_dim: the size of the vector's feature layer.
        belief_channels: how many leading image channels hold belief mass; None: all but the
            last (the map).
    """

    def __init__(
        self,
        observation_space: gym.spaces.Dict,
        features_dim: int = 256,
        channels: tuple[int, ...] = (32, 64, 64),
        vector_dim: int = 128,
        belief_channels: int | None = None,
    ) -> None:
        spaces = getattr(observation_space, "spaces", {})
        image, vector = spaces.get("image"), spaces.get("vector")
        if not (isinstance(image, gym.spaces.Box) and len(image.shape) == 3
                and isinstance(vector, gym.spaces.Box) and len(vector.shape) == 1):
            raise ValueError(
                "BeliefImageExtractor needs a Dict observation space with an 'image' Box "
                f"(C, H, W) and a 'vector' Box (D,), got {observation_space}"
            )
        n_channels = image.shape[0]
        belief_channels = n_channels - 1 if belief_channels is None else belief_channels
        if features_dim < 1 or vector_dim < 1 or not channels or not (
            0 <= belief_channels <= n_channels
        ):
            raise ValueError(
                f"features_dim and vector_dim must be >= 1, channels non-empty and "
                f"belief_channels in [0, {n_channels}], got {features_dim}, {vector_dim}, "
                f"{channels}, {belief_channels}"
            )
        super().__init__(observation_space, features_dim + vector_dim)
        self.belief_channels = belief_channels
        layers: list[nn.Module] = []
        in_channels = n_channels
        for i, out_channels in enumerate(channels):
            stride = 1 if i == 0 else 2
            layers += [nn.Conv2d(in_channels, out_channels, 3, stride=stride, padding=1),
                       nn.ReLU()]
            in_channels = out_channels
        self.cnn = nn.Sequential(*layers, nn.AdaptiveAvgPool2d(4), nn.Flatten())
        self.image_linear = nn.Sequential(nn.Linear(16 * in_channels, features_dim), nn.ReLU())
        self.vector_linear = nn.Sequential(nn.Linear(vector.shape[0], vector_dim), nn.ReLU())

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        image = rescaled_belief(observations["image"], self.belief_channels)
        features = self.image_linear(self.cnn(image))
        return torch.cat([features, self.vector_linear(observations["vector"])], dim=1)
