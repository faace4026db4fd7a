"""A rollout as the learner takes it: T steps of B environments, time-major, with the
policy inputs as a tree of (T * B, ...) tensors. Rollout workers collect it
(`hamnet.trainer.collection.rollout_worker`), chunks carry it over Zenoh
(`hamnet.policy.chunk_codec`, from workers or the policy service), the learner merges the
environments of several into one. It lives with the policy, below the trainer, because the
policy service records rollouts too. Shapes: T steps, B environments, A action, R reward terms.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TypeVar

import torch
from torch import Tensor

from hamnet.policy.networks import PolicyInputs
from hamnet.runtime.trees import zip_trees


@dataclass(frozen=True)
class Rollout:
    """T steps of B environments, time-major."""

    inputs: PolicyInputs
    """Policy inputs, every tensor (T * B, ...), step t's rows at [t * B, (t + 1) * B)."""
    actions: Tensor
    """(T, B, A) raw actions taken."""
    log_prob: Tensor
    """(T, B) their log-density under the acting policy."""
    values: Tensor
    """(T, B, R) values per reward term of the states acted in."""
    rewards: Tensor
    """(T, B, R) reward terms as the sim gave them."""
    final_values: Tensor
    """(T, B, R) V(final state) where an episode was truncated at step t, else 0."""
    dones: Tensor
    """(T, B) bool: the episode ended at this step (terminated or truncated)."""
    next_values: Tensor
    """(B, R) values of the states after the last step."""
    success: Tensor
    """(T, B) bool: the episode ended in success at this step."""
    guide: Tensor | None = None
    """(T, B, A) the scripted pusher's raw action in each state acted in: the target of PPO's
    imitation term (`GuideConfig`); None where the run has no guide."""


RolloutLike = TypeVar("RolloutLike")
"""A `Rollout` or DAgger's `Demonstrations`: the same layout of (T, B, ...) fields and
time-major (T * B, ...) inputs."""


def cat_rows(trees: list) -> object:
    """Concatenate trees of (B, ...) tensors along rows: (len * B, ...), time-major."""
    return zip_trees(trees, lambda tensors: torch.cat(tensors, dim=0))


PER_ENVIRONMENT = ("next_values", "first")
"""Fields of a rollout (or of DAgger's `Demonstrations`) that are (B, ...), not (T, B, ...)."""


def merge_environments(rollouts: list[RolloutLike]) -> RolloutLike:
    """One rollout of the environments of several (same T), in the given order; DAgger's
    demonstrations likewise."""
    steps = len(rollouts[0].dones)

    def side_by_side(tensors: list[Tensor]) -> Tensor:
        """(T * B_i, ...) rows of each, time-major -> (T * sum B_i, ...), time-major."""
        per_step = [x.reshape(steps, -1, *x.shape[1:]) for x in tensors]  # (T, B_i, ...)
        merged = torch.cat(per_step, dim=1)
        return merged.reshape(-1, *merged.shape[2:])

    fields = {
        f.name: torch.cat(
            [getattr(r, f.name) for r in rollouts], dim=0 if f.name in PER_ENVIRONMENT else 1
        )
        for f in dataclasses.fields(rollouts[0])
        if f.name != "inputs" and getattr(rollouts[0], f.name) is not None
    }
    inputs = zip_trees([r.inputs for r in rollouts], side_by_side)
    return dataclasses.replace(rollouts[0], inputs=inputs, **fields)
