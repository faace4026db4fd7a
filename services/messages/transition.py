"""Transition (sim -> policy, trainer, monitor): the outcome of the command answering state
k, encoded by the sim and decoded by every consumer with one function.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from hamnet.proto.common_pb2 import Header
from hamnet.proto.sim_pb2 import Transition
from hamnet.runtime.tensor import field_array, to_tensor


class Outcome(Protocol):
    """What a Transition is encoded from (the sim's `StepResult`)."""

    episode_ids: np.ndarray  # (B,) int64, before any auto-reset
    reward_terms: np.ndarray  # (B, R)
    terminated: np.ndarray  # (B,) bool
    truncated: np.ndarray  # (B,) bool
    success: np.ndarray  # (B,) bool


@dataclass(frozen=True)
class TransitionIn:
    """Transition k: the outcome of the command that answered state k."""

    step: int
    """k, `Header.step`."""
    stamp_ns: int
    """`Header.stamp_ns`."""
    episode_ids: np.ndarray
    """(B,) int64, before any reset."""
    reward_names: tuple[str, ...]
    """R names, the column order of `reward_terms`."""
    reward_terms: np.ndarray
    """(B, R) float32."""
    terminated: np.ndarray
    """(B,) bool."""
    truncated: np.ndarray
    """(B,) bool."""
    success: np.ndarray
    """(B,) bool."""


def decode(message: Transition) -> TransitionIn:
    """Transition k, its reward terms one column per reward name.

    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    names = tuple(message.reward_names)
    terms = np.array(field_array(message, "reward_terms", np.float32, (None, len(names))))
    b = len(terms)
    flags = {
        name: np.array(field_array(message, name, np.bool_, (b,)))
        for name in ("terminated", "truncated", "success")
    }
    ids = np.array(field_array(message, "episode_ids", np.int64, (b,)))
    header = message.header
    return TransitionIn(header.step, header.stamp_ns, ids, names, terms, **flags)


def encode(result: Outcome, reward_names: Sequence[str], step: int) -> Transition:
    """Transition k: the outcome of command k (episode ids before any auto-reset)."""
    message = Transition(header=Header(step=step), reward_names=list(reward_names))
    to_tensor(result.episode_ids.astype(np.int64), message.episode_ids)  # (B,)
    to_tensor(result.reward_terms.astype(np.float32), message.reward_terms)  # (B, R)
    to_tensor(result.terminated.astype(bool), message.terminated)  # (B,)
    to_tensor(result.truncated.astype(bool), message.truncated)  # (B,)
    to_tensor(result.success.astype(bool), message.success)  # (B,)
    return message
