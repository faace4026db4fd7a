"""A recurrent policy evaluated over sequences for learning (the student of DAgger, issue
15): the GRUs unrolled over T collected steps of B environments, the memory reset to the
initial memory wherever an episode starts, so gradients flow through time inside an
episode and never across its start (backpropagation through time truncated to the window).

The inputs are stored as the rollout stores them: time-major rows (step t's B environments
are rows t*B ... t*B + B - 1, `trajectory.cat_rows`), each with the memory the policy acted
with; only step 0's memory is read, the later ones are recomputed with gradients. The acting
path zeroes the memory of new episodes in `inputs.begin_step`; `episode_starts` gives the
same steps from the rollout's episode ends. Shapes: T steps, B environments, A action
components, R reward terms, H memory.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import torch
from torch import Tensor

from hamnet.policy.networks import PolicyInputs
from hamnet.policy.policy import Policy
from hamnet.runtime.trees import take_rows


@dataclass(frozen=True)
class SequenceEvaluation:
    """`Policy.evaluate` of every step of a sequence, stacked."""

    log_prob: Tensor
    """(T, B) log-density of the given actions."""
    entropy: Tensor
    """(T, B) entropy of the action distribution."""
    values: Tensor
    """(T, B, R) value per reward term."""
    mean: Tensor
    """(T, B, A) mean of the action distribution."""
    memories: Tensor
    """(T, B, H) memory after each step (it has read that step's observation)."""


def episode_starts(dones: Tensor, first: Tensor) -> Tensor:
    """(T, B) bool: the steps that begin an episode.

    Args:
        dones: (T, B) the episode ended (terminated or truncated) at this step.
        first: (B,) step 0 begins an episode (the rollout's window opened on a reset).
    """
    return torch.cat((first[None].bool(), dones[:-1].bool()), dim=0)


def evaluate_sequence(
    policy: Policy, inputs: PolicyInputs, actions: Tensor, starts: Tensor
) -> SequenceEvaluation:
    """Unroll a recurrent `policy` over T steps with memory resets, with gradients.

    Args:
        policy: a policy with memory (`Policy.memory_width` > 0).
        inputs: T * B time-major rows; the memory of rows 0 ... B - 1 starts the unroll.
        actions: (T, B, A) the actions to score (the teacher's, for DAgger).
        starts: (T, B) bool: the step begins an episode, so the memory before it is
            replaced by the initial memory (step 0 included).
    Raises:
        ValueError: a feed-forward policy, or inputs, actions and starts of other sizes.
    """
    steps, b = starts.shape
    if not policy.memory_width:
        raise ValueError(f"{policy.architecture} has no memory to unroll")
    rows = len(inputs.observation.base)
    if rows != steps * b or actions.shape[:2] != starts.shape or inputs.memory is None:
        raise ValueError(
            f"inputs of {rows} rows, actions {tuple(actions.shape[:2])} and "
            f"starts {(steps, b)} do not make one (T, B) sequence with memory"
        )
    initial = policy.initial_memory(b)  # (B, H)
    memory = inputs.memory[:b]  # (B, H)
    outputs = []
    for t in range(steps):
        memory = torch.where(starts[t, :, None], initial, memory)  # cuts the gradient too
        step = take_rows(inputs, torch.arange(t * b, (t + 1) * b, device=starts.device))
        out = policy.evaluate(dataclasses.replace(step, memory=memory), actions[t])
        outputs.append(out)
        memory = out.memory
    stack = lambda name: torch.stack([getattr(out, name) for out in outputs])
    return SequenceEvaluation(
        stack("log_prob"), stack("entropy"), stack("values"), stack("mean"), stack("memory")
    )
