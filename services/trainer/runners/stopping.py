"""Stopping a run between two steps: every long loop of training (a rollout's steps, an
update's minibatches, a wait for workers) takes a `running` callable and raises
InterruptedError once it turns False. The unfinished rollout or update is left behind, and
the run goes back to the state before its iteration (`Runner.run`), so a run stopped by
Ctrl-C, SIGTERM or its duration saves within the launcher's grace period and resumes
exactly from there."""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager


def always() -> bool:
    """A `running` that never stops a loop."""
    return True


def check(running: Callable[[], bool]) -> None:
    """Raise InterruptedError once `running()` turns False."""
    if not running():
        raise InterruptedError("stopped")


@contextmanager
def until_signalled() -> Iterator[Callable[[], bool]]:
    """A `running` that turns False at the first SIGINT or SIGTERM (the handlers of a process
    without a `Service`, which installs its own); the previous handlers come back after."""
    stop = threading.Event()
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {signum: signal.signal(signum, lambda *_: stop.set()) for signum in signals}
    try:
        yield lambda: not stop.is_set()
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
