"""Running standardisation of the policy's non-geometric inputs, carried with the weights.

Every group of the observation (context, base, scene_query, object_query) is standardised
with a running mean and variance per column, as the authors standardise observations
(`NormalizeEnv`, ham/src/ham/env/env/wrap/normalize_env.py). The statistics are buffers of
the policy, so the weights the trainer publishes carry them and the policy service
standardises exactly as training did. The trainer folds in each rollout's observations
after its update, so acting and evaluating one rollout see the same statistics (PPO's
ratio starts at 1). Before any statistics every input reads 0, its standardised value at
an unknown mean: raw inputs (object angular velocity reaches 16 rad/s) never enter the
network, and the trainer's first iteration fills the statistics before any action is
learned from (`Runner.iterate`). UniCORN tokens are left alone, as the authors leave their embeddings
(`constlist`, rss_train.yaml:496-510). Standardised values are clipped to +-`clip`.
"""

from __future__ import annotations

import dataclasses

import torch
from torch import Tensor, nn

from hamnet.policy.observation import NetworkInputs, ObservationSpec

GROUPS = tuple(field.name for field in dataclasses.fields(NetworkInputs))
"""The observation's groups, each standardised on its own."""


class InputNormalizer(nn.Module):
    """Per-column running statistics of every observation group."""

    def __init__(self, spec: ObservationSpec, clip: float = 5.0, eps: float = 1e-6) -> None:
        super().__init__()
        self.clip, self.eps = clip, eps
        for group in GROUPS:
            width = spec.width(group)
            self.register_buffer(f"{group}_mean", torch.zeros(width))
            self.register_buffer(f"{group}_var", torch.ones(width))
        self.register_buffer("count", torch.zeros(()))

    def forward(self, observation: NetworkInputs) -> NetworkInputs:
        """The observation standardised and clipped, group by group ((B, width) each); zeros
        before any statistics."""
        if not self.count:
            return dataclasses.replace(
                observation,
                **{group: torch.zeros_like(getattr(observation, group)) for group in GROUPS},
            )
        changes = {}
        for group in GROUPS:
            mean, var = getattr(self, f"{group}_mean"), getattr(self, f"{group}_var")
            value = getattr(observation, group)
            changes[group] = ((value - mean) / (var + self.eps).sqrt()).clamp(-self.clip, self.clip)
        return dataclasses.replace(observation, **changes)

    @torch.no_grad()
    def update(self, observation: NetworkInputs) -> None:
        """Fold a batch of N raw observations ((N, width) per group) into the statistics."""
        if len(observation.context) == 0:
            return
        count = self.count.clone()
        for group in GROUPS:
            mean, var = getattr(self, f"{group}_mean"), getattr(self, f"{group}_var")
            new_mean, new_var, total = merge_moments(mean, var, count, getattr(observation, group))
            mean.copy_(new_mean)
            var.copy_(new_var)
        self.count.copy_(total)


def merge_moments(
    mean: Tensor, var: Tensor, count: Tensor, batch: Tensor
) -> tuple[Tensor, Tensor, Tensor]:
    """Mean, variance and count of a stream after folding in `batch` (N, *shape): Chan et
    al.'s parallel update, in float64, results in the dtype of `mean`.

    Args:
        mean, var: (*shape) statistics of the `count` samples so far.
        count: () samples so far (0 for none: the batch's own moments are returned).
    """
    batch = batch.detach().double().reshape(-1, *mean.shape)
    n = batch.shape[0]
    total = count.double() + n
    batch_mean, batch_var = batch.mean(0), batch.var(0, unbiased=False)
    delta = batch_mean - mean.double()
    new_mean = mean.double() + delta * n / total
    new_var = (var.double() * count + batch_var * n + delta.square() * count * n / total) / total
    return new_mean.to(mean.dtype), new_var.to(var.dtype), total.to(count.dtype)
