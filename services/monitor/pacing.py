"""Which steps the monitor draws, and the success rate it plots: small pure state machines,
fed with step numbers, wall times and flags (no Rerun, no Zenoh).

Several topics carry each step (state, clouds, action, transition): the first one of a new
step decides whether that step is drawn, and every later message of the step follows the
decision, so a drawn step shows the robot, clouds and module weights of one same step.
"""

from __future__ import annotations

from collections import OrderedDict, deque

import numpy as np

REMEMBERED_STEPS = 64
"""Decisions kept; a message of an older step is skipped (it is late anyway)."""


class FramePacer:
    """Draws a new step only when `min_interval_s` has passed since the last drawn one."""

    def __init__(self, min_interval_s: float) -> None:
        self.min_interval_s = min_interval_s
        self._decided: OrderedDict[int, bool] = OrderedDict()
        self._last_drawn_at = -np.inf
        self.drawn = 0
        """Steps drawn so far."""
        self.skipped = 0
        """Steps skipped so far."""

    def draw(self, step: int, now: float) -> bool:
        """Whether step `step` is drawn; `now` is the wall time of the message, s (monotonic)."""
        decision = self._decided.get(step)
        if decision is not None:
            return decision
        decision = now - self._last_drawn_at >= self.min_interval_s
        if decision:
            self._last_drawn_at = now
            self.drawn += 1
        else:
            self.skipped += 1
        self._decided[step] = decision
        if len(self._decided) > REMEMBERED_STEPS:
            self._decided.popitem(last=False)
        return decision


class SuccessRate:
    """Share of successes among the last `window` finished episodes."""

    def __init__(self, window: int) -> None:
        self._outcomes: deque[bool] = deque(maxlen=window)
        self.finished = 0
        """Episodes finished so far."""

    def add(self, done: np.ndarray, success: np.ndarray) -> int:
        """Count the episodes that ended in one step.

        Args:
            done: (B,) bool, the episode ended (terminated or truncated).
            success: (B,) bool, it ended in success.
        Returns:
            how many episodes ended.
        """
        ended = success[done]  # (K,)
        self._outcomes.extend(bool(s) for s in ended)
        self.finished += len(ended)
        return len(ended)

    @property
    def rate(self) -> float:
        """Success rate over the window, in [0, 1]; NaN before any episode ended."""
        return float(np.mean(self._outcomes)) if self._outcomes else float("nan")
