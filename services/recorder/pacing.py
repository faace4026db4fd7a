"""When and where replayed messages go: recorded time to wall time, the namespace a key is
republished in, and the grouping of messages into steps for stepped replay.

Pure functions of recorded keys, times and step numbers; the replay shell does the I/O.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import TypeVar

from hamnet.runtime import keys

T = TypeVar("T")


def remap_key(key: str, namespace: str) -> str:
    """`key` moved into `namespace`: `hamnet/<any>/<path>` becomes `hamnet/<namespace>/<path>`;
    keys outside `hamnet/` are kept as they are."""
    parts = key.split("/", 2)
    if len(parts) == 3 and parts[0] == keys.ROOT:
        return f"{keys.ROOT}/{keys.check_segment('namespace', namespace)}/{parts[2]}"
    return key


@dataclass(frozen=True)
class ReplayClock:
    """Maps recorded log times onto a monotonic wall clock, scaled by a speed factor."""

    first_log_ns: int
    """Log time of the first message replayed, Unix ns."""
    start_s: float
    """time.monotonic() at which that first message is due, s."""
    speed: float
    """Recorded seconds per wall-clock second (2.0: twice as fast)."""

    def due_s(self, log_time_ns: int) -> float:
        """time.monotonic() at which the message logged at `log_time_ns` is due, s."""
        return self.start_s + (log_time_ns - self.first_log_ns) / 1e9 / self.speed


def group_steps(items: Iterable[T], step_of: Callable[[T], int | None]) -> Iterator[list[T]]:
    """Cut a recording into steps, in order.

    A step runs from a marker (an item whose `step_of` is not None, e.g. a robot state)
    whose step number is above every marker's before it, up to the next such marker. A
    marker that repeats an earlier number (a state sent again while the sim waits) stays in
    the current step; items before the first marker belong to the first step.

    Args:
        items: the recording, in order.
        step_of: the step number of a marker, None for every other item.
    """
    group: list[T] = []
    last: int | None = None
    for item in items:
        step = step_of(item)
        if step is not None:
            if last is not None and step > last:
                yield group
                group = []
            last = step if last is None else max(last, step)
        group.append(item)
    if group:
        yield group
