"""The UniCORN geometry encoder: a point cloud (B, P, 3) to tokens (B, 1 + K, D), [EMB]
first (paper Fig. pretraining_network and section "Training UniCORN"; Table tab:network).

Patchify: K centres by farthest-point sampling, each with its k nearest points, centred on
it. Tokenize: a per-point MLP max-pooled over the patch (a mini-PointNet, so the order of
the points inside a patch does not matter). Add a sinusoidal embedding of the centre (a
linear map of sin/cos features), prepend the learned [EMB] token, and run pre-LN
transformer layers. Everything is batched: no Python loop runs per cloud or per patch
(FPS loops over the K centres, each step for the whole batch).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from hamnet.perception.clouds import farthest_point_sample, gather, knn
from hamnet.perception.config import EncoderConfig


def patchify(points: torch.Tensor, num_patches: int, patch_size: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Centres and centre-normalised patches of clouds (B, P, 3).

    Returns:
        centres (B, K, 3) and patches (B, K, k, 3) (each point minus its centre), m.
    """
    centres = gather(points, farthest_point_sample(points, num_patches))  # (B, K, 3)
    patches = gather(points, knn(points, centres, patch_size))  # (B, K, k, 3)
    return centres, patches - centres[:, :, None, :]


class SinusoidalEmbedding(nn.Module):
    """Sin/cos of each coordinate at geometric wavelengths, mapped linearly to the width."""

    def __init__(self, config: EncoderConfig) -> None:
        super().__init__()
        shortest = 4e-3  # m
        exponents = torch.linspace(0.0, 1.0, config.frequencies)
        wavelengths = shortest * (config.max_wavelength / shortest) ** exponents  # (F,)
        self.register_buffer("angular", 2 * math.pi / wavelengths, persistent=False)
        self.project = nn.Linear(6 * config.frequencies, config.width)

    def forward(self, centres: torch.Tensor) -> torch.Tensor:
        """centres (B, K, 3) m -> (B, K, D)."""
        phase = centres[..., None] * self.angular  # (B, K, 3, F)
        features = torch.cat([phase.sin(), phase.cos()], -1).flatten(-2)  # (B, K, 6F)
        return self.project(features)


class PatchTokenizer(nn.Module):
    """Per-point MLP, max-pooled over the patch, then a linear map to the width."""

    def __init__(self, config: EncoderConfig) -> None:
        super().__init__()
        hidden = config.tokenizer_hidden
        self.point = nn.Sequential(
            nn.Linear(3, hidden), nn.GELU(), nn.Linear(hidden, 2 * hidden), nn.GELU()
        )
        self.out = nn.Linear(2 * hidden, config.width)

    def forward(self, patches: torch.Tensor) -> torch.Tensor:
        """patches (B, K, k, 3) -> tokens (B, K, D)."""
        return self.out(self.point(patches).amax(-2))


class UniCORN(nn.Module):
    """Point clouds (B, P, 3) to tokens (B, 1 + num_patches, width); token 0 is [EMB]."""

    def __init__(self, config: EncoderConfig | None = None) -> None:
        super().__init__()
        self.config = config = config if config is not None else EncoderConfig()
        self.tokenizer = PatchTokenizer(config)
        self.position = SinusoidalEmbedding(config)
        self.emb = nn.Parameter(torch.randn(1, 1, config.width) * 0.02)
        self.layers = nn.ModuleList(
            nn.TransformerEncoderLayer(
                config.width, config.heads, config.mlp_ratio * config.width, dropout=0.0,
                activation="gelu", batch_first=True, norm_first=True,
            )  # fmt: skip
            for _ in range(config.depth)
        )
        self.norm = nn.LayerNorm(config.width)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        """points (B, P, 3), m -> tokens (B, 1 + K, D)."""
        config = self.config
        if points.ndim != 3 or points.shape[1:] != (config.num_points, 3):
            raise ValueError(f"expected clouds (B, {config.num_points}, 3), got {tuple(points.shape)}")
        centres, patches = patchify(points, config.num_patches, config.patch_size)
        tokens = self.tokenizer(patches) + self.position(centres)  # (B, K, D)
        tokens = torch.cat([self.emb.expand(len(points), -1, -1), tokens], 1)  # (B, 1 + K, D)
        for layer in self.layers:
            tokens = layer(tokens)
        return self.norm(tokens)
