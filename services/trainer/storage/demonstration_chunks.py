"""DAgger's `Demonstrations` <-> a RolloutChunk, as `hamnet rollout --algo dagger` workers
stream them to `hamnet trainer --algo dagger` on `trainer/<w>/demonstrations`.

A chunk carries what the student's update needs and nothing else of the teacher's inputs:
the student's inputs per step (`inputs.*`, per-episode tokens once per distinct row, as
PPO's chunks, `hamnet.trainer.storage.rollout_chunks`), the teacher's labels (`labels`,
`label_values`), whose action was executed (`teacher_acted`), which environments begin an
episode at step 0 (`first`; with `dones` the GRU's memory resets), reward terms, dones and
successes (the episode statistics), the object's true velocity (`object_velocity`, the
optional velocity loss's target) and the SHA-256 of the teacher checkpoint that labelled it
(`teacher_sha256`): the trainer refuses, counts and drops another teacher's chunks.
Shapes: T steps, B environments, A action components, R reward terms, V the velocity's 6.
"""

from __future__ import annotations

from collections.abc import Callable

from hamnet.policy.chunk_codec import decode_batch, encode_rollout
from hamnet.policy.policy import Policy
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime import contract
from hamnet.runtime.tensor import PayloadError
from hamnet.trainer.algorithms.dagger import Demonstrations
from hamnet.trainer.storage.rollout_chunks import Arrived, arrived_decoder

DEMONSTRATIONS = contract.topic("trainer/<w>/demonstrations")

_SHAPES = {
    "labels": "TBA",
    "label_values": "TBR",
    "teacher_acted": "TB",
    "first": "B",
    "rewards": "TBR",
    "dones": "TB",
    "success": "TB",
    "object_velocity": "TBV",
}
"""The demonstrations' fields other than the student's inputs, by their dimensions' letters."""

_FLAGS = ("teacher_acted", "first", "dones", "success")
"""Those that are bool."""


def encode_demonstrations(
    demos: Demonstrations, version: int, step: int, teacher_sha256: str
) -> RolloutChunk:
    """The chunk of `demos`, the student acting with weights `version`, labelled by the
    teacher whose checkpoint hashes to `teacher_sha256`; `step` counts the worker's chunks."""
    chunk = encode_rollout(demos, version, step)
    chunk.teacher_sha256 = teacher_sha256
    return chunk


def decode_demonstrations(
    chunk: RolloutChunk, student: Policy, teacher_sha256: str
) -> Demonstrations:
    """The demonstrations in `chunk`, checked for `student` as `chunks.decode_rollout` checks
    a rollout, once they are the teacher `teacher_sha256`'s.

    Raises:
        PayloadError: another teacher labelled them (reason `teacher`), or a tensor is
            missing, unknown, mistyped, misshapen, not finite, or unreadable by `student`.
    """
    if chunk.teacher_sha256 != teacher_sha256:
        raise PayloadError(
            "teacher",
            f"labelled by the teacher {chunk.teacher_sha256[:12] or '(none)'}, "
            f"this run distils {teacher_sha256[:12]}: give the worker this run's "
            "--teacher",
        )
    return decode_batch(chunk, Demonstrations, _SHAPES, _FLAGS, student)


def demonstrations_decoder(
    teacher_sha256: str,
) -> Callable[[Policy], Callable[[str, bytes], Arrived]]:
    """For `stream.Streamed`: the inbox decoder of a student's demonstrations chunks,
    labelled by the teacher `teacher_sha256`."""
    return lambda student: arrived_decoder(
        lambda chunk: decode_demonstrations(chunk, student, teacher_sha256)
    )
