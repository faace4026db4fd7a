"""A rollout as the learner takes it: T steps of B environments, time-major, with the
policy inputs as a tree of (T * B, ...) tensors. Rollout workers collect it
(`hamnet.trainer.rollout`), chunks carry it over Zenoh (`hamnet.trainer.chunks`, from workers
or the policy service), the learner merges the environments of several into one.
Shapes: T steps, B environments, A action, R reward terms.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import torch
from torch import Tensor

from hamnet.policy.networks import PolicyInputs
from hamnet.trainer.trees import zip_trees


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


def cat_rows(trees: list) -> object:
    """Concatenate trees of (B, ...) tensors along rows: (len * B, ...), time-major."""
    return zip_trees(trees, lambda tensors: torch.cat(tensors, dim=0))


def merge_environments(rollouts: list[Rollout]) -> Rollout:
    """One rollout of the environments of several (same T), in the given order."""
    steps = len(rollouts[0].actions)

    def side_by_side(tensors: list[Tensor]) -> Tensor:
        """(T * B_i, ...) rows of each, time-major -> (T * sum B_i, ...), time-major."""
        per_step = [x.reshape(steps, -1, *x.shape[1:]) for x in tensors]  # (T, B_i, ...)
        merged = torch.cat(per_step, dim=1)
        return merged.reshape(-1, *merged.shape[2:])

    fields = {
        f.name: torch.cat([getattr(r, f.name) for r in rollouts], dim=0 if f.name == "next_values" else 1)
        for f in dataclasses.fields(Rollout) if f.name != "inputs"
    }  # fmt: skip
    return Rollout(inputs=zip_trees([r.inputs for r in rollouts], side_by_side), **fields)
