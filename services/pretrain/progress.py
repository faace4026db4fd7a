"""Progress lines for long pre-training commands (tqdm is not a dependency): done/total,
rate and time left, at most once per period, on stderr through logging."""

from __future__ import annotations

import logging
import time

log = logging.getLogger(__name__)


def format_duration(seconds: float) -> str:
    """`1h02m`, `3m05s` or `42s`."""
    seconds = round(seconds)
    if seconds >= 3600:
        return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
    if seconds >= 60:
        return f"{seconds // 60}m{seconds % 60:02d}s"
    return f"{seconds}s"


class Progress:
    """Counts `unit`s done out of `total` and logs a rate line every `period_s` seconds."""

    def __init__(self, what: str, total: int, unit: str, period_s: float, done: int = 0) -> None:
        self.what, self.total, self.unit, self.period_s = what, total, unit, period_s
        self.start_done, self.done = done, done
        self.started = self.last = time.monotonic()

    def line(self, extra: str = "") -> str:
        """The current progress line."""
        elapsed = max(time.monotonic() - self.started, 1e-9)
        rate = (self.done - self.start_done) / elapsed
        left = format_duration((self.total - self.done) / rate) if rate > 0 else "?"
        share = 100.0 * self.done / max(self.total, 1)
        return (
            f"{self.what}: {self.done}/{self.total} {self.unit} ({share:.1f}%), "
            f"{rate:.1f} {self.unit}/s, {left} left{extra}"
        )

    def advance(self, count: int, extra: str = "") -> None:
        """Add `count` done; log a line when a period has passed or all is done."""
        self.done += count
        now = time.monotonic()
        if now - self.last >= self.period_s or self.done >= self.total:
            self.last = now
            log.info(self.line(extra))
