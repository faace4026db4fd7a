"""How the bridge paces its states on the robot's clock (`BridgeLoopConfig`) and times the
commands that answer them, without Zenoh.

`paced` gives the time of the next state: one policy period after the last, unless the
robot's clock has moved more than a period away from it. `CommandLatency` keeps when each
recent state went out and, over the newest LATENCY_WINDOW commands, how long each took to
be executed from its state's publication: its median and p99 go into the shell's rate line
and into health as figures.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np

from hamnet.runtime.errors import ConfigError
from hamnet.runtime.shell_config import Flattened, ReportConfig

Pose = tuple[float, float, float, float, float, float, float]
"""Position (m) and quaternion wxyz."""

LATENCY_WINDOW = 1000
"""Commands over which the state-to-command latency percentiles are taken."""
LATENCY_HORIZON = 100
"""States kept for timing their commands: a later command is stale anyway."""


@dataclass(frozen=True)
class BridgeLoopConfig:
    """Pace, goal and reporting of the bridge."""

    policy_period_s: float = 0.1
    """One state per this many seconds; commands must hold this many seconds of samples at
    the driver's period (run safety with the same `--trajectory.policy-period-s` and
    `--trajectory.control-rate-hz 1000`)."""
    goal_pose: Pose = (0.5, 0.0, 0.05, 1.0, 0.0, 0.0, 0.0)
    """The object's goal published in every state: position (m), quaternion wxyz."""
    pose_max_age_steps: int = 5
    """Oldest object pose estimate put in a state, in states (its frames' state to this one)."""
    max_steps: int = 0
    """Exit after this many states (0: run until stopped)."""
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)

    def __post_init__(self) -> None:
        if self.max_steps < 0:
            raise ConfigError(f"--max-steps must be >= 0, got {self.max_steps}")
        if self.pose_max_age_steps < 1:
            raise ConfigError(f"--pose-max-age-steps must be >= 1, got {self.pose_max_age_steps}")


def paced(tick: float, now: float, period_s: float) -> float:
    """When the next state is due on the robot's clock: `tick`, or `now` when the clock is
    more than a period past it (the loop fell behind: no burst to catch up) or more than a
    period before it (the clock went back, as a reconnected robot's may: waiting for it
    would halve the rate)."""
    return tick if abs(now - tick) <= period_s else now


class CommandLatency:
    """Seconds from a state's publication to the execution of its command."""

    def __init__(self) -> None:
        self.published: dict[int, float] = {}
        """When each recent state went out (step -> monotonic s), to time its command."""
        self.latencies: deque[float] = deque(maxlen=LATENCY_WINDOW)
        """Seconds from a state's publication to the execution of its command, newest last."""

    def published_state(self, step: int, now: float) -> None:
        """State `step` went out at `now` (monotonic s)."""
        self.published[step] = now
        self.published.pop(step - LATENCY_HORIZON, None)

    def executed(self, step: int, now: float) -> None:
        """The command answering state `step` was executed at `now`: timed once, if that
        state went out recently."""
        if step in self.published:
            self.latencies.append(now - self.published.pop(step))

    def figures(self) -> dict[str, float]:
        """The latency percentiles of the recent commands (a window of the newest, not of
        a rate line's period), in ms, and their count; empty before the first."""
        if not self.latencies:
            return {}
        median, p99 = 1e3 * np.percentile(self.latencies, [50, 99])
        return {
            "command_latency_median_ms": median,
            "command_latency_p99_ms": p99,
            "command_latency_count": len(self.latencies),
        }
