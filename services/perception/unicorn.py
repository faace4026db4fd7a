"""The UniCORN geometry encoder: a point cloud (B, P, 3) to tokens (B, K + 1, D), [EMB]
last (paper Fig. pretraining_network and section "Training UniCORN"; Table tab:network;
where the paper leaves it open, the authors' code: ham/models/cloud/unicorn.py and
point_mae.py).

Patchify: K centres by farthest-point sampling, each with its k nearest points sorted by
distance; the patch is re-centred on its mean (GroupFPSV2 recenter, point_mae.py:1074-1075)
and its points taken relative to it (unicorn.py:122). Tokenize: an MLP over the flattened
patch (k x 3 -> 256 -> 256 -> D, Linear-LN-GELU, MLPPatchEncoder, point_mae.py:769-816),
plus a sinusoidal embedding of the centre (a linear map of sin/cos features). The learned
[EMB] token goes after the patch tokens (z_ctx appended, unicorn.py:153-154; the policy
reads the last token, rss_train.yaml:324), then pre-LN transformer layers. Everything is
batched: no Python loop runs per cloud or per patch (FPS loops over the K centres, each
step for the whole batch).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from hamnet.perception.cloud_ops import farthest_point_sample, gather, knn
from hamnet.perception.config import EncoderConfig


def patchify(
    points: torch.Tensor, num_patches: int, patch_size: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """Centres and centre-relative patches of clouds (B, P, 3).

    Returns:
        centres (B, K, 3), the mean of each patch, and patches (B, K, k, 3) (each point
        minus its patch's centre, nearest to the FPS seed first), m.
    """
    seeds = gather(points, farthest_point_sample(points, num_patches))  # (B, K, 3)
    patches = gather(points, knn(points, seeds, patch_size))  # (B, K, k, 3), sorted
    centres = patches.mean(dim=2)  # (B, K, 3)
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
    """An MLP over the flattened patch: k x 3 -> tokenizer_hidden -> width, Linear -> LN ->
    GELU between layers, linear output (the authors' MLPPatchEncoder)."""

    def __init__(self, config: EncoderConfig) -> None:
        super().__init__()
        dims = (3 * config.patch_size, *config.tokenizer_hidden, config.width)
        layers: list[nn.Module] = []
        for i, o in zip(dims[:-2], dims[1:-1]):
            layers += [nn.Linear(i, o), nn.LayerNorm(o), nn.GELU()]
        self.mlp = nn.Sequential(*layers, nn.Linear(dims[-2], dims[-1]))

    def forward(self, patches: torch.Tensor) -> torch.Tensor:
        """patches (B, K, k, 3) -> tokens (B, K, D)."""
        return self.mlp(patches.flatten(-2))


class UniCORN(nn.Module):
    """Point clouds (B, P, 3) to tokens (B, num_patches + 1, width); the last is [EMB]."""

    def __init__(self, config: EncoderConfig | None = None) -> None:
        super().__init__()
        self.config = config = config if config is not None else EncoderConfig()
        self.tokenizer = PatchTokenizer(config)
        self.position = SinusoidalEmbedding(config)
        self.emb = nn.Parameter(torch.randn(1, 1, config.width) * 0.02)
        self.layers = nn.ModuleList(
            nn.TransformerEncoderLayer(
                config.width,
                config.heads,
                config.mlp_ratio * config.width,
                dropout=0.0,
                activation="gelu",
                batch_first=True,
                norm_first=True,
            )
            for _ in range(config.depth)
        )
        self.norm = nn.LayerNorm(config.width)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        """points (B, P, 3), m -> tokens (B, K + 1, D)."""
        config = self.config
        if points.ndim != 3 or points.shape[1:] != (config.num_points, 3):
            raise ValueError(
                f"expected clouds (B, {config.num_points}, 3), got {tuple(points.shape)}"
            )
        with torch.autocast(points.device.type, enabled=False):  # rank neighbours in float32
            centres, patches = patchify(points.float(), config.num_patches, config.patch_size)
        tokens = self.tokenizer(patches) + self.position(centres)  # (B, K, D)
        tokens = torch.cat([tokens, self.emb.expand(len(points), -1, -1)], 1)  # (B, K + 1, D)
        for layer in self.layers:
            tokens = layer(tokens)
        return self.norm(tokens)
