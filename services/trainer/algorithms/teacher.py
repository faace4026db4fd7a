"""DAgger's teacher and student: the frozen PPO policy that labels, and the check that a run's
architecture can be distilled into.

The teacher is a policy checkpoint the PPO trainer wrote (or a shipped policy by name); its
SHA-256 names it in every demonstrations chunk and in the run's snapshot, so a run resumes,
and learns, only from the teacher it was distilled from.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from hamnet.policy.policy import Policy
from hamnet.policy.registry import architecture
from hamnet.policy.shipped import read_weights, resolve
from hamnet.policy.weights import WeightsError, policy_from, sha256


class DaggerError(ValueError):
    """A teacher or student DAgger cannot use (one line, for the command line)."""


@dataclass(frozen=True)
class Teacher:
    """The frozen teacher of a run."""

    policy: Policy
    path: Path
    sha256: str
    """Of the checkpoint file's bytes."""


def load_teacher(path: Path) -> Teacher:
    """The teacher in the policy checkpoint `path` (or the shipped policy of that name).

    Raises:
        DaggerError: no such file, not a policy checkpoint, or a student's (no privileged
            inputs, or recurrent): a student cannot label for another.
    """
    try:
        data = resolve(path).read_bytes()
    except OSError as error:
        raise DaggerError(f"cannot read teacher {path}: {error.strerror}") from None
    try:
        policy = policy_from(read_weights(path))  # a shipped one checked against its card
    except WeightsError as error:
        raise DaggerError(f"teacher {path} is not a policy checkpoint: {error}") from None
    if not policy.config.privileged or policy.config.recurrent:
        raise DaggerError(
            f"teacher {path} is a {policy.architecture!r} policy, a student's "
            "architecture: the teacher must be a privileged feed-forward policy "
            "trained by PPO (hamnet trainer)"
        )
    return Teacher(policy.requires_grad_(False), Path(path), sha256(data))


def check_student(name: str) -> None:
    """DaggerError unless `name` is a student architecture: no privileged input, and memory
    for `evaluate_sequence` to unroll."""
    config = architecture(name).config
    if config.privileged or not config.recurrent:
        raise DaggerError(
            f"--architecture {name} is not a student (no privileged inputs, "
            "recurrent): DAgger distils into one, e.g. 'student'"
        )
