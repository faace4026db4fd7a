"""The encoders pre-training compares, by name (`TrainConfig.encoder`): clouds (B, P, 3) to
tokens (B, K + 1, D), patch tokens first and a global token ([EMB]) last, on the same
patches (FPS centres, kNN members: `patch_members`).

- unicorn: perception's UniCORN, trained (the weights perception ships).
- random-frozen: UniCORN at its random initialisation, frozen: only the decoder learns, so
  it measures what training the encoder adds.
- pointnet: a plain PointNet (Qi et al. 2017): a shared per-point MLP, max-pooled over all
  points for the global token and over each patch's points for the patch tokens.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import nn

from hamnet.perception.cloud_ops import farthest_point_sample, gather, knn
from hamnet.perception.config import EncoderConfig
from hamnet.perception.unicorn import UniCORN
from hamnet.pretrain.config import EncoderKind


def patch_members(points: torch.Tensor, config: EncoderConfig) -> torch.Tensor:
    """Indices (B, K, k) of each patch's points in clouds (B, P, 3): the patches UniCORN's
    `patchify` forms (the same FPS seeds and kNN), as indices for labels and pooling."""
    seeds = gather(points, farthest_point_sample(points, config.num_patches))  # (B, K, 3)
    return knn(points, seeds, config.patch_size)  # (B, K, k)


class PointNet(nn.Module):
    """Per-point MLP 3 -> 64 -> 128 -> D, max-pooled per patch and over the cloud."""

    def __init__(self, config: EncoderConfig) -> None:
        super().__init__()
        self.config = config
        self.mlp = nn.Sequential(
            nn.Linear(3, 64), nn.ReLU(), nn.Linear(64, 128), nn.ReLU(), nn.Linear(128, config.width)
        )

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        """points (B, P, 3), m -> tokens (B, K + 1, D)."""
        features = self.mlp(points)  # (B, P, D)
        patches = gather(features, patch_members(points, self.config)).amax(2)  # (B, K, D)
        return torch.cat([patches, features.amax(1, keepdim=True)], 1)


def _frozen_unicorn(config: EncoderConfig) -> nn.Module:
    encoder = UniCORN(config)
    encoder.requires_grad_(False)
    return encoder


ENCODERS: dict[str, Callable[[EncoderConfig], nn.Module]] = {
    "unicorn": UniCORN,
    "random-frozen": _frozen_unicorn,
    "pointnet": PointNet,
}
"""Encoder builders by `EncoderKind`."""


def build_encoder(kind: EncoderKind, config: EncoderConfig) -> nn.Module:
    """A fresh encoder of `kind` (random weights from torch's global generator)."""
    return ENCODERS[kind](config)
