"""The contact decoder of UniCORN pre-training (paper appendix "Details on pretraining
pipeline"): a patch token of one cloud, conditioned on the other cloud's [EMB] token, to the
logit that the patch touches the other shape.

Residual conditional-MLP blocks with conditional batch norm (CBN, as in Occupancy Networks,
Mescheder et al. 2019): batch norm without affine parameters, then a scale and shift mapped
from the condition by one linear layer each. Scales start at 1 and shifts at 0, so an
untrained CBN is a plain batch norm.
"""

from __future__ import annotations

import torch
from torch import nn

from hamnet.pretrain.config import DecoderConfig


class ConditionalBatchNorm(nn.Module):
    """BN(x) * gamma(c) + beta(c) over rows x (N, W) with conditions c (N, C)."""

    def __init__(self, width: int, condition_width: int) -> None:
        super().__init__()
        self.norm = nn.BatchNorm1d(width, affine=False)
        self.gamma = nn.Linear(condition_width, width)
        self.beta = nn.Linear(condition_width, width)
        nn.init.zeros_(self.gamma.weight)
        nn.init.ones_(self.gamma.bias)
        nn.init.zeros_(self.beta.weight)
        nn.init.zeros_(self.beta.bias)

    def forward(self, x: torch.Tensor, condition: torch.Tensor) -> torch.Tensor:
        return self.norm(x) * self.gamma(condition) + self.beta(condition)


class ConditionalResidualBlock(nn.Module):
    """x + fc1(relu(cbn1(fc0(relu(cbn0(x | c)))) | c)); fc1 starts at zero (identity block)."""

    def __init__(self, width: int, condition_width: int) -> None:
        super().__init__()
        self.norm0 = ConditionalBatchNorm(width, condition_width)
        self.fc0 = nn.Linear(width, width)
        self.norm1 = ConditionalBatchNorm(width, condition_width)
        self.fc1 = nn.Linear(width, width)
        nn.init.zeros_(self.fc1.weight)

    def forward(self, x: torch.Tensor, condition: torch.Tensor) -> torch.Tensor:
        hidden = self.fc0(torch.relu(self.norm0(x, condition)))
        return x + self.fc1(torch.relu(self.norm1(hidden, condition)))


class ContactDecoder(nn.Module):
    """Patch tokens (N, D) and the other cloud's [EMB] tokens (N, D) to contact logits (N,)."""

    def __init__(self, token_width: int, config: DecoderConfig | None = None) -> None:
        super().__init__()
        config = config if config is not None else DecoderConfig()
        self.project = nn.Linear(token_width, config.width)
        self.blocks = nn.ModuleList(
            ConditionalResidualBlock(config.width, token_width) for _ in range(config.blocks)
        )
        self.norm = ConditionalBatchNorm(config.width, token_width)
        self.out = nn.Linear(config.width, 1)

    def forward(self, patch: torch.Tensor, condition: torch.Tensor) -> torch.Tensor:
        """patch (N, D), condition (N, D) -> logits (N,)."""
        x = self.project(patch)  # (N, W)
        for block in self.blocks:
            x = block(x, condition)
        return self.out(torch.relu(self.norm(x, condition))).squeeze(-1)
