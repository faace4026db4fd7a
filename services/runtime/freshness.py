"""Which steps of a producer a consumer acts on, across restarts of that producer.

A consumer answering a producer's steps (the policy and the safety filter answer the sim's
states) keeps a watermark, the newest step it acted on, and ignores older steps: they are
late copies the loop has moved past. Steps alone cannot tell a restarted producer from late
messages, since a new sim counts from 0 again. So every message header carries the run of
its producer (`Header.run`, drawn anew at each start, `hamnet.runtime.pubsub.PROCESS_RUN`):
a message of another run than the watermark's starts afresh, whatever its step. A step
further ahead of the watermark than any real producer can get between two messages of one
run (`max_jump`) is refused rather than adopted: adopting a forged or corrupt step 10^12
would make every real step after it look stale for good. A consumer that answers each step
once (the policy, perception) keeps its last answer with the watermark (`Answered`), and
sends it again when the producer repeats that step. Pure bookkeeping, no Zenoh.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Generic, TypeVar

A = TypeVar("A")

MAX_STEP_JUMP = 10_000
"""Default of `Watermark.max_jump`: how far ahead of the watermark a step of the same run
may be, in steps. A sim publishes every step and repeats its state while it waits, so a
consumer that sees one run misses few of its steps; 10,000 policy steps (17 minutes at the
paper's 10 Hz) leave room for a consumer that was stalled that long and refuse any step
counter that is not a real one."""


class Verdict(Enum):
    """What to do with a step."""

    FRESH = "fresh"
    """Newer than the watermark in the same run: act on it."""
    RESTART = "restart"
    """A step of another run than the one followed (or the very first message): drop
    whatever belongs to the old run, `restart`, then act on it."""
    REPEAT = "repeat"
    """The watermark's own step again (the producer resends while it waits)."""
    STALE = "stale"
    """Older than the watermark: drop it."""
    IMPLAUSIBLE = "implausible"
    """Further ahead than `max_jump`: drop it, the watermark stays."""


@dataclass
class Watermark:
    """The newest (run, step) a consumer acted on."""

    max_jump: int = MAX_STEP_JUMP
    """Largest step increase accepted within one run."""
    run: int | None = None
    """Run of the producer followed; None before its first message."""
    step: int | None = None
    """Newest step acted on in `run`; None before the first."""

    def __post_init__(self) -> None:
        if self.max_jump < 1:
            raise ValueError(f"max_jump must be >= 1, got {self.max_jump}")

    def judge(self, run: int, step: int) -> Verdict:
        """The verdict on `step` of `run`, without changing the watermark."""
        if run != self.run:
            return Verdict.RESTART
        if self.step is None:
            return Verdict.FRESH
        if step == self.step:
            return Verdict.REPEAT
        if step < self.step:
            return Verdict.STALE
        return Verdict.IMPLAUSIBLE if step - self.step > self.max_jump else Verdict.FRESH

    def judge_step(self, step: int) -> Verdict:
        """The verdict on `step` of the watermark's own run, for messages that answer the
        producer's steps without carrying its run (perception's tokens for the sim's
        states carry perception's run); never RESTART."""
        return Verdict.FRESH if self.step is None else self.judge(self.run, step)

    def restart(self, run: int) -> bool:
        """Follow `run` from now on, with no step acted on yet; True when it replaces a run
        followed before (the producer restarted), False on the very first message."""
        restarted = self.run is not None
        self.run, self.step = run, None
        return restarted

    def advance(self, step: int) -> None:
        """Record that `step` of the current run was acted on (the watermark keeps the
        newest step)."""
        self.step = step if self.step is None else max(self.step, step)


@dataclass
class Answered(Generic[A]):
    """The answer a consumer sent to the newest step it acted on, with that step's watermark:
    a repeated step gets the same answer again, another run of the producer is followed."""

    watermark: Watermark = field(default_factory=Watermark)
    """The producer's run followed and the newest step answered in it."""
    message: A | None = None
    """The answer to the watermark's step; None before the first answer of a run."""

    def follow(self, run: int, step: int) -> Verdict:
        """The verdict on `step` of `run`; a message of another run is followed at once (the
        old run's answer is dropped). RESTART only when it replaces a run followed before:
        the very first message is FRESH. REPEAT only when there is an answer to send again."""
        verdict = self.watermark.judge(run, step)
        if verdict is Verdict.RESTART:
            self.message = None
            if not self.watermark.restart(run):
                return Verdict.FRESH
        return verdict

    def answer(self, step: int, message: A) -> None:
        """Record `message` as the answer to `step` of the run followed."""
        self.watermark.advance(step)
        self.message = message
