"""One rate line for every service loop: a shell counts what its loop does (`tick`,
`count`, `sample`) and every `report_period_s` the reporter logs one line the shell words
(`line`) and puts the figures the shell chooses (`figures`) into its health reports.

The clock is injected, so the periods are tested without sleeping and without Zenoh.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Window:
    """What a loop did between two rate lines."""

    seconds: float
    """Length of the window, s (> 0)."""
    counts: Mapping[str, float]
    """Counts by name over the window (a name never counted is 0)."""
    samples: Mapping[str, Sequence[float]]
    """Measured values by name over the window (e.g. seconds per step)."""

    def count(self, name: str) -> float:
        """The total of `name` over the window (0 when never counted)."""
        return self.counts.get(name, 0)

    def rate(self, *names: str) -> float:
        """The summed counts of `names` per second."""
        return sum(self.count(name) for name in names) / self.seconds

    def median_ms(self, name: str) -> float:
        """Median of the samples of `name` (seconds) in ms; nan without samples."""
        values = self.samples.get(name, ())
        return 1e3 * float(np.median(values)) if len(values) else float("nan")


Line = Callable[[Window], str]
"""The text of a rate line, from the window and whatever else the shell knows."""
Figures = Callable[[Window], Mapping[str, float]]
"""The health figures of a window, by name."""


class LoopReport:
    """Counts of one loop and its periodic rate line and health figures."""

    def __init__(
        self,
        period_s: float,
        line: Line,
        *,
        figures: Figures | None = None,
        set_figure: Callable[[str, float], None] | None = None,
        logger: logging.Logger = log,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """
        Args:
            period_s: seconds between rate lines (> 0).
            line: words the rate line; logged at info level on `logger`.
            figures: the figures of each window, handed to `set_figure` (e.g.
                `Service.set_figure`, so the health reports carry them).
            clock: monotonic seconds.
        """
        if not period_s > 0:
            raise ValueError(f"period_s must be > 0, got {period_s}")
        if figures is not None and set_figure is None:
            raise ValueError("figures need set_figure, where they go")
        self.period_s, self.line, self.figures, self.set_figure = (
            period_s,
            line,
            figures,
            set_figure,
        )
        self.logger, self.clock = logger, clock
        self.counts: Counter[str] = Counter()
        """Counts since the last rate line (updated in place, so it can be shared)."""
        self.samples: dict[str, list[float]] = {}
        """Measured values since the last rate line."""
        self._totals: dict[str, float] = {}
        """The newest value of each running total (`total`)."""
        self._base: dict[str, float] = {}
        """Each running total when the current window began."""
        self.started = clock()
        """When the current window began."""

    def count(self, name: str, n: float = 1) -> None:
        """Add `n` to the count `name` of the current window."""
        self.counts[name] += n

    def sample(self, name: str, value: float) -> None:
        """Record one measured value of `name` (e.g. seconds of one step)."""
        self.samples.setdefault(name, []).append(value)

    def total(self, **totals: float) -> None:
        """The newest values of running totals a shell keeps anyway (e.g. frames drawn so
        far): the window counts what they grew by since it began (or since first given)."""
        for name, value in totals.items():
            self._totals[name] = value
            self.counts[name] = value - self._base.setdefault(name, value)

    def tick(self, **counts: float) -> Window | None:
        """One turn of the loop: add `counts`, then report when a period has passed.

        Returns:
            The window just reported, or None when no report was due.
        """
        for name, n in counts.items():
            self.counts[name] += n
        if self.clock() - self.started < self.period_s:
            return None
        return self.flush()

    def flush(self) -> Window | None:
        """Report the current window now (e.g. on the way out) and start the next one.

        Returns:
            The window reported, or None when no time has passed since the last.
        """
        now = self.clock()
        if now <= self.started:
            return None
        window = Window(
            now - self.started,
            dict(self.counts),
            {name: list(values) for name, values in self.samples.items()},
        )
        self.logger.info("%s", self.line(window))
        if self.figures is not None:
            for name, value in self.figures(window).items():
                self.set_figure(name, float(value))
        self.restart()
        return window

    def restart(self) -> None:
        """Forget the current window and start a new one now (e.g. after a slow start that
        is not the loop's rate)."""
        self.counts.clear()
        self.samples.clear()
        self._base = dict(self._totals)
        self.started = self.clock()
