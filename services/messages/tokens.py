"""PerceptionTokens (perception -> policy, monitor): the clouds and UniCORN tokens of state
k, decoded by every consumer with one function.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from hamnet.messages.fields import Spec, arrays, batch_size
from hamnet.proto.common_pb2 import Header
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.runtime.tensor import to_tensor

if TYPE_CHECKING:  # the consumers that read numpy only (the monitor) need no torch
    import torch

CLOUDS = ("object_cloud", "environment_cloud", "local_cloud")
TOKENS = ("object_tokens", "local_tokens", "global_tokens")


class Percepts(Protocol):
    """What PerceptionTokens is encoded from (`hamnet.perception.core.Percepts`)."""

    object_cloud: torch.Tensor  # (B, P, 3)
    environment_cloud: torch.Tensor  # (B, P, 3)
    local_cloud: torch.Tensor  # (B, P, 3)
    object_tokens: torch.Tensor  # (B, N, D)
    local_tokens: torch.Tensor  # (B, N, D)
    global_tokens: torch.Tensor  # (B, N, D)


@dataclass(frozen=True)
class TokensIn:
    """PerceptionTokens k decoded (float32 clouds and tokens); a field the message leaves
    out is None."""

    step: int
    """k: the state step the tokens answer."""
    episode_ids: np.ndarray | None = None
    """(B,) int64."""
    object_cloud: np.ndarray | None = None
    """(B, P, 3) m."""
    environment_cloud: np.ndarray | None = None
    """(B, P, 3) m."""
    local_cloud: np.ndarray | None = None
    """(B, P, 3) m."""
    object_tokens: np.ndarray | None = None
    """(B, N, D)."""
    local_tokens: np.ndarray | None = None
    """(B, N, D)."""
    global_tokens: np.ndarray | None = None
    """(B, N, D)."""
    encoder_version: int = 0
    """Version of the encoder weights (0: random weights)."""
    stamp_ns: int = 0
    """`Header.stamp_ns`."""

    @property
    def tokens(self) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        """Object, local and global tokens, (B, N, D) each: the policy's token inputs."""
        return self.object_tokens, self.local_tokens, self.global_tokens


def decode(
    message: PerceptionTokens,
    required: Iterable[str] = (),
    token_shape: tuple[int | None, int | None] = (None, None),
) -> TokensIn:
    """PerceptionTokens k, every field it carries checked against one batch size B.

    Args:
        required: fields that must be set (names of `TokensIn`'s arrays).
        token_shape: (N, D) every token field must have (None: any).
    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    specs = {
        "episode_ids": Spec(np.int64),
        **{name: Spec(np.float32, (None, 3)) for name in CLOUDS},
        **{name: Spec(np.float32, token_shape) for name in TOKENS},
    }
    b = batch_size(message, specs, ("episode_ids", "object_cloud", "object_tokens"))
    decoded = arrays(message, specs, b, required)
    header = message.header
    return TokensIn(
        header.step, encoder_version=message.encoder_version, stamp_ns=header.stamp_ns, **decoded
    )


def encode(
    percepts: Percepts, step: int, episode_ids: np.ndarray, version: int
) -> PerceptionTokens:
    """PerceptionTokens k: clouds (B, P, 3) and tokens (B, 1 + K, D), float32."""
    message = PerceptionTokens(header=Header(step=step), encoder_version=version)
    to_tensor(np.asarray(episode_ids, dtype=np.int64), message.episode_ids)  # (B,)
    for name in (*CLOUDS, *TOKENS):
        value = getattr(percepts, name).detach().cpu().numpy().astype(np.float32)
        to_tensor(value, getattr(message, name))
    return message
