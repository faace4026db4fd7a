"""PolicyAction (policy -> safety, trainer, monitor): the policy's answer to state k.

Non-finite values and any shape pass the decoder, as the contract lets them through: the
safety filter's stage 1 rejects them and the rejection becomes an event; the monitor shows
them.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from hamnet.messages.fields import Spec, arrays
from hamnet.messages.robot_state import StateIn
from hamnet.proto.common_pb2 import Header
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.runtime.tensor import to_tensor

if TYPE_CHECKING:  # the consumers that read numpy only (safety, monitor) need no torch
    import torch


class Answer(Protocol):
    """What PolicyAction is encoded from: `hamnet.policy.policy.Action`, or any object with
    an `action`. Its `log_prob` (B,), `values` (B, R) and `module_weights` (B, L, M) are
    encoded when it has them (a scripted policy has none); torch tensors or numpy arrays."""

    action: torch.Tensor | np.ndarray  # (B, 21)


@dataclass(frozen=True)
class ActionIn:
    """PolicyAction k decoded; a field the message leaves out is None."""

    step: int
    """k: the state step the action was computed for."""
    action: np.ndarray | None
    """Raw action, (B, 21) float32 expected; NaN, Inf and any shape pass."""
    episode_ids: np.ndarray | None
    """(N,) int64 episodes the action was computed for."""
    log_prob: np.ndarray | None = None
    """(B,) float32."""
    values: np.ndarray | None = None
    """(B, R) float32 critic values, one per reward group."""
    module_weights: np.ndarray | None = None
    """(B, L, M) float32 soft module weights (None: a policy without modules)."""
    policy_version: int = 0
    """`Header.policy_version`: the weights that computed it."""
    stamp_ns: int = 0
    """`Header.stamp_ns`."""
    action_space: str = "joint"
    """What the residual components ask for (`ModelConfig.action_space`; "joint" when the
    message leaves it empty)."""

    def stale(self, state: StateIn) -> np.ndarray | None:
        """(B,) rows computed for another episode than the state's, or None (unchecked: no
        ids sent, or a wrong batch, which the filter's stage 1 rejects whole)."""
        if self.episode_ids is None or self.episode_ids.shape != state.episode_ids.shape:
            return None
        return self.episode_ids != state.episode_ids


_FIELDS = {
    "action": Spec(np.float32, None, finite=False),
    "episode_ids": Spec(np.int64, ()),
    "log_prob": Spec(np.float32, None, finite=False),
    "values": Spec(np.float32, (None,), finite=False),
    "module_weights": Spec(np.float32, (None, None), finite=False),
}


def decode(message: PolicyAction, required: Iterable[str] = ()) -> ActionIn:
    """PolicyAction k; `required` names the fields the consumer reads.

    Raises:
        PayloadError: `missing` (a required field), `dtype` (not float32 / int64), `shape`
            (bytes differ from the shape, or the rank of values or module weights).
    """
    header = message.header
    decoded = arrays(message, _FIELDS, None, required)
    return ActionIn(
        header.step,
        policy_version=header.policy_version,
        stamp_ns=header.stamp_ns,
        action_space=message.action_space or "joint",
        **decoded,
    )


def encode(
    step: int,
    version: int,
    episode_ids: np.ndarray,
    answer: Answer,
    deterministic: bool,
    action_space: str = "joint",
) -> PolicyAction:
    """PolicyAction k: action (B, 21) in `action_space`, and the log_prob (B,), values
    (B, R) and module weights (B, L, M) that `answer` has, as float32."""
    message = PolicyAction(
        header=Header(step=step, policy_version=version),
        deterministic=deterministic,
        action_space=action_space,
    )
    to_tensor(np.asarray(episode_ids, dtype=np.int64), message.episode_ids)
    for name in ("action", "log_prob", "values", "module_weights"):
        value = getattr(answer, name, None)
        if value is not None:
            to_tensor(_float32(value), getattr(message, name))
    return message


def _float32(value: torch.Tensor | np.ndarray) -> np.ndarray:
    """A tensor (detached, on the CPU) or an array as a float32 array, without importing torch."""
    if hasattr(value, "detach"):
        value = value.detach().cpu().float().numpy()
    return np.asarray(value, dtype=np.float32)
