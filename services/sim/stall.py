"""When the closed loop stalls: the sim runs but no command has come for a while.

A sim waiting in lock-step looks the same whether the policy is thinking or the loop is
broken (a consumer that takes every new state for a stale one, a dead safety service), so
the sim, which sees every command arrive, calls a stall once `limit_s` passes without one,
counts it (an event in its health reports, which `hamnet up` sums in its summary) and logs
when it ends. Waiting for the very first command is start-up, not a stall. Pure
bookkeeping on times the caller passes in, so tests need no clock.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class StallWatch:
    """Times since the last command, and the stalls they made."""

    limit_s: float
    """A wait longer than this, s, is a stall."""
    last_command: float | None = None
    """When the last command arrived (time.monotonic()); None before the first."""
    stalled_since: float | None = None
    """Start of the stall under way (the last command's time); None while the loop runs."""
    stalls: int = 0
    """Stalls begun so far."""

    def __post_init__(self) -> None:
        if self.limit_s <= 0:
            raise ValueError(f"limit_s must be > 0, got {self.limit_s}")

    def commanded(self, now: float) -> float | None:
        """A command arrived at `now`; returns how long the stall it ends lasted, s (None
        when none was under way)."""
        ended = None if self.stalled_since is None else now - self.stalled_since
        self.last_command, self.stalled_since = now, None
        return ended

    def check(self, now: float) -> bool:
        """True once per stall: when `now` is the first check past `limit_s` without a
        command (after the first one)."""
        if self.last_command is None or self.stalled_since is not None:
            return False
        if now - self.last_command <= self.limit_s:
            return False
        self.stalled_since = self.last_command
        self.stalls += 1
        return True
