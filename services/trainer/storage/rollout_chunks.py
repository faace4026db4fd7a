"""The trainer's side of the rollout chunks workers stream: PPO's `Rollout` decoded from a
RolloutChunk (the wire format is `hamnet.policy.chunk_codec`; DAgger's `Demonstrations`
travel the same way, `hamnet.trainer.storage.demonstration_chunks`), and the inbox decoder
that queues each chunk with the version of the weights that acted in it (`Arrived`).
A chunk that does not fit the trainer's policy raises `PayloadError`: the inbox counts and
drops it, so a bad chunk never reaches an update. Shapes: T steps, B environments.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from hamnet.policy.chunk_codec import decode_batch
from hamnet.policy.policy import Policy
from hamnet.policy.rollout_record import Rollout
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime.codec import decode
from hamnet.trainer.algorithms.dagger import Demonstrations

_FLAGS = ("dones", "success")
"""Rollout fields that are (T, B) bool."""

_SHAPES = {
    "actions": "TBA",
    "log_prob": "TB",
    "values": "TBR",
    "rewards": "TBR",
    "final_values": "TBR",
    "dones": "TB",
    "next_values": "BR",
    "success": "TB",
}
"""The rollout's fields other than its inputs, by their dimensions' letters."""

_OPTIONAL = {"guide": "TBA"}
"""Fields a rollout carries only in some runs (the scripted pusher's actions: a guided run)."""

Batch = Rollout | Demonstrations
"""What a chunk carries: T steps of B environments with the policy inputs of each."""


def decode_rollout(chunk: RolloutChunk, policy: Policy) -> Rollout:
    """The rollout in `chunk`, checked for `policy` (the trainer's): every tensor named,
    typed, shaped and finite, and the inputs of its first row ones the policy can read.

    Raises:
        PayloadError: a tensor is missing, unknown, of the wrong dtype or shape, not finite,
            or inputs the policy cannot evaluate.
    """
    return decode_batch(chunk, Rollout, _SHAPES, _FLAGS, policy, _OPTIONAL)


@dataclass(frozen=True)
class Arrived:
    """A decoded chunk as the trainer queues it."""

    version: int
    """Version of the weights that acted in it (`header.policy_version`)."""
    rollout: Batch
    """PPO's Rollout, or DAgger's Demonstrations."""
    source: str
    """The service that sent it, `service/worker` (`header.source`): whose liveliness token
    tells whether it is still there."""
    arrived_s: float = 0.0
    """When Zenoh delivered it, monotonic s (set by the trainer)."""


def arrived_decoder(read: Callable[[RolloutChunk], Batch]) -> Callable[[str, bytes], Arrived]:
    """An inbox decoder (key, payload) -> `Arrived` (version, what `read` makes of the chunk,
    source); `read` raises PayloadError for a chunk that does not fit."""

    def decode_chunk(key: str, payload: bytes) -> Arrived:
        chunk = decode(RolloutChunk, payload, finite=False)  # `read` checks each tensor
        header = chunk.header
        return Arrived(header.policy_version, read(chunk), header.source)

    return decode_chunk


def chunk_decoder(policy: Policy) -> Callable[[str, bytes], Arrived]:
    """An inbox decoder (key, payload) -> `Arrived` (version, Rollout, source) for `policy`."""
    return arrived_decoder(lambda chunk: decode_rollout(chunk, policy))
