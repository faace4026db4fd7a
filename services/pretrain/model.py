"""The contact model of pre-training: a Siamese encoder (both clouds through the same
weights) and the contact decoder, with its loss (binary cross-entropy per patch, balanced,
both roles of each pair).

Consumes clouds (B, P, 3) and point labels (B, P); produces patch logits and the loss.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from hamnet.perception.config import EncoderConfig
from hamnet.pretrain.batch import cross_pairs, patch_labels
from hamnet.pretrain.config import DecoderConfig, EncoderKind
from hamnet.pretrain.decoder import ContactDecoder
from hamnet.pretrain.encoders import build_encoder


class ContactModel(nn.Module):
    """Encoder of `kind` plus contact decoder."""

    def __init__(
        self, kind: EncoderKind, architecture: EncoderConfig, decoder: DecoderConfig
    ) -> None:
        super().__init__()
        self.kind, self.architecture = kind, architecture
        self.encoder = build_encoder(kind, architecture)
        self.decoder = ContactDecoder(architecture.width, decoder)

    def train(self, mode: bool = True) -> ContactModel:
        """A frozen encoder stays in eval mode."""
        super().train(mode)
        if self.kind == "random-frozen":
            self.encoder.eval()
        return self

    def freeze_encoder(self, frozen: bool) -> None:
        """Stop (or resume) the encoder's learning; a random-frozen encoder never learns."""
        self.encoder.requires_grad_(not frozen and self.kind != "random-frozen")

    def patches(
        self, points_a: torch.Tensor, points_b: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Patch tokens and conditions (2 B K, D) of both roles (see `batch.cross_pairs`)."""
        tokens = self.encoder(torch.cat([points_a, points_b]))  # (2B, K + 1, D)
        return cross_pairs(*tokens.split(len(points_a)))

    def labels(self, points_a, points_b, labels_a, labels_b) -> torch.Tensor:
        """(2 B K,) bool patch labels in the order of `patches`."""
        k = self.architecture
        return torch.cat(
            [patch_labels(points_a, labels_a, k), patch_labels(points_b, labels_b, k)]
        ).flatten()

    def forward(self, points_a: torch.Tensor, points_b: torch.Tensor) -> torch.Tensor:
        """Contact logits (2 B K,) of every patch, both roles (no resampling)."""
        return self.decoder(*self.patches(points_a, points_b))


@dataclass(frozen=True)
class LossTerms:
    """What one batch's loss reports."""

    loss: torch.Tensor
    """Binary cross-entropy over every patch, balanced by `batch.balance_weights` (a scalar
    with its graph)."""
    accuracy: float
    """Balanced share of patches classified right at probability 0.5 (the same weights)."""
    positive_share: float
    """Share of positive patches in the batch."""


def contact_loss(
    model: ContactModel,
    points_a: torch.Tensor,
    points_b: torch.Tensor,
    labels: torch.Tensor,
    weights: torch.Tensor,
) -> LossTerms:
    """Weighted BCE of the decoder on every patch of both roles, each patch once.

    Args:
        points_a, points_b: (B, P, 3) augmented clouds, m.
        labels: (2 B K,) bool patch labels (`ContactModel.labels` of the same clouds).
        weights: (2 B K,) `batch.balance_weights` of `labels`, summing to 1.
    """
    target = labels.float()
    logits = model(points_a, points_b)  # (2BK,)
    per_patch = nn.functional.binary_cross_entropy_with_logits(logits, target, reduction="none")
    right = ((logits > 0).float() == target).float()
    return LossTerms(
        (weights * per_patch).sum(), float((weights * right).sum()), float(target.mean())
    )
