"""One training batch of contact pairs: augmentation of both clouds together, patch labels,
and the weights that balance positive and negative patches to a target share (paper appendix "Details on
pretraining pipeline", Table tab:pretrain-params).

Patch label rule: a patch is in contact when any of its k points lies inside the other
shape (the point labels of `pairs.py`). The paper labels patches without saying how points
combine; "any" keeps a patch that clips into the other shape by one point positive, which is
what a policy must not miss.
"""

from __future__ import annotations

import torch

from hamnet.perception.cloud_ops import quaternion_matrix
from hamnet.perception.config import EncoderConfig
from hamnet.pretrain.config import AugmentConfig
from hamnet.pretrain.encoders import patch_members


def augment(
    points_a: torch.Tensor,
    points_b: torch.Tensor,
    config: AugmentConfig,
    generator: torch.Generator,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Both clouds (B, P, 3) of each pair rotated, scaled and moved together, then noised.

    x' = s R x + t + n: R by an angle U(-rotation, rotation) about a uniform axis, s =
    e^U(-log_scale, log_scale), t ~ U(-translation, translation)^3, n ~ N(0, noise^2) per point.
    """
    b = len(points_a)
    uniform = lambda *shape: 2 * torch.rand(*shape, generator=generator) - 1  # U(-1, 1)
    axis = torch.nn.functional.normalize(torch.randn(b, 3, generator=generator), dim=-1)  # (B, 3)
    half = 0.5 * config.rotation * uniform(b, 1)  # (B, 1), rad
    rotation = quaternion_matrix(torch.cat([half.cos(), half.sin() * axis], -1))  # (B, 3, 3)
    scale = torch.exp(config.log_scale * uniform(b, 1, 1))  # (B, 1, 1)
    shift = config.translation * uniform(b, 1, 3)  # (B, 1, 3), m

    def move(points: torch.Tensor) -> torch.Tensor:
        moved = scale * torch.einsum("bij,bpj->bpi", rotation, points) + shift
        return moved + config.noise * torch.randn(moved.shape, generator=generator)

    return move(points_a), move(points_b)


def patch_labels(points: torch.Tensor, labels: torch.Tensor, config: EncoderConfig) -> torch.Tensor:
    """(B, K) bool: a patch of clouds (B, P, 3) is positive when any of its points is
    (point labels (B, P) bool)."""
    members = patch_members(points, config)  # (B, K, k)
    return labels.gather(1, members.flatten(1)).view(members.shape).any(-1)


def balance_weights(labels: torch.Tensor, fraction: float) -> torch.Tensor:
    """Loss weights (M,) of the flat patch labels (M,) bool, summing to 1: f / P on each of
    the P positives and (1 - f) / N on each of the N negatives (all weight on one kind when
    the batch lacks the other).

    This is the paper's resampling (a positive drawn with probability f / P, a negative with
    (1 - f) / N) in expectation, without its draws: drawn with replacement, the few positives
    of a batch appear many times over in the decoder's input, and its batch norm learns to
    find them from the batch statistics (resampled batches scored AUROC 0.92 with batch
    statistics and 0.75 with the running ones, in evaluation). Every patch goes through the
    decoder once instead.
    """
    positives = labels.float()
    count = positives.sum()
    if count == 0 or count == len(labels):
        return torch.full_like(positives, 1.0 / len(labels))
    return torch.where(labels, fraction / count, (1 - fraction) / (len(labels) - count))


def cross_pairs(
    tokens_a: torch.Tensor, tokens_b: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Both roles of each pair: A's patches conditioned on B's [EMB], then B's on A's.

    Args:
        tokens_a, tokens_b: (B, K + 1, D), [EMB] last.
    Returns:
        patch tokens (2 B K, D) and their conditions (2 B K, D), A-major then B.
    """
    k = tokens_a.shape[1] - 1

    def rows(patches: torch.Tensor, emb: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return patches.flatten(0, 1), emb[:, None, :].expand(-1, k, -1).flatten(0, 1)

    pa, ca = rows(tokens_a[:, :k], tokens_b[:, -1])
    pb, cb = rows(tokens_b[:, :k], tokens_a[:, -1])
    return torch.cat([pa, pb]), torch.cat([ca, cb])


def step_generator(seed: int, step: int) -> torch.Generator:
    """The generator of one step's batch and augmentation: a function of (seed,
    step) alone, so a resumed run draws what the uninterrupted one would have."""
    return torch.Generator().manual_seed(seed * 1_000_003 + step)


def batch_index(step: int, batch_size: int, count: int, seed: int) -> torch.Tensor:
    """Pairs of step `step`: the epoch's permutation of `count` pairs (seeded by (seed,
    epoch)) cut into consecutive batches; the last short batch of an epoch is skipped."""
    per_epoch = max(count // batch_size, 1)
    epoch, position = divmod(step, per_epoch)
    order = torch.randperm(count, generator=torch.Generator().manual_seed(seed * 7919 + epoch))
    return order[position * batch_size : (position + 1) * batch_size]
