"""Where replayed messages go and in which steps: the namespace a key is republished in, and
the grouping of messages into steps for stepped replay (recorded time to wall time is
`hamnet.runtime.recordings.ReplayClock`).

Pure functions of recorded keys and step numbers; the replay shell does the I/O.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
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
