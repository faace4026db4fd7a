"""A clock that moves only when a test says so, for cores that take an injected clock."""

from __future__ import annotations


class Clock:
    """Seconds since `start`, set by the test through `now`."""

    def __init__(self, start: float = 0.0) -> None:
        self.now = start

    def __call__(self) -> float:
        return self.now
