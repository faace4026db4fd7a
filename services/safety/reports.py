"""What the safety loop reports besides its commands: rejection events, rate-limited clip
events and per-stage statistics of the filter's commands (as `Notice`s, handed to an
injected `emit`), and the counts and latencies of the rate line in the log
(`hamnet.runtime.loop_report`). Time comes from an injected clock, as in
`hamnet.safety.supervisor`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hamnet.fr3.limits import ACTION_DIM
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.safety.filter import SafeOutput
from hamnet.safety.pipeline import FilterResult
from hamnet.safety.stages import Rejection
from hamnet.safety.stats import (
    StageReport,
    StageStats,
    StatsAccumulator,
    empty_stats,
    merge,
    summarize,
)

log = logging.getLogger(__name__)

CLIP_KINDS = {
    "action_magnitude": "CLIPPED_MAGNITUDE",
    "cartesian_clip": "CLIPPED_CARTESIAN",
    "joint_limits": "CLIPPED_JOINT_LIMIT",
    "torque_preclip": "CLIPPED_TORQUE",
}
"""Stages whose clipping becomes an event, with its kind (a `SafetyEventKind` name; the EMA
smooths every step: statistics only)."""

REJECTIONS = {
    Rejection.NONFINITE: ("REJECTED_NONFINITE", "the action holds NaN or Inf"),
    Rejection.SHAPE: ("REJECTED_SHAPE", f"the action is not (B, {ACTION_DIM})"),
    Rejection.STATE: ("REJECTED_NONFINITE", "the robot state holds NaN or Inf"),
    Rejection.EPISODE: (
        "REJECTED_EPISODE",
        ("the action was computed for an episode that has ended (the environment was reset)"),
    ),
}
"""Event kind and reason of each rejection code of stage 1."""

STATISTICS = "SAFETY_EVENT_KIND_UNSPECIFIED"
"""The kind of the periodic per-stage statistics event."""


@dataclass(frozen=True)
class Notice:
    """One safety event at state step `step`."""

    kind: str
    """A `SafetyEventKind` name."""
    step: int
    env_ids: np.ndarray
    """(K,) environments concerned."""
    stage: str = ""
    reason: str = ""
    stats: tuple[StageStats, ...] = ()


def rejections(filtered: FilterResult, step: int) -> list[Notice]:
    """One notice per rejection reason present in a filter call."""
    notices = []
    for code, (kind, reason) in REJECTIONS.items():
        env_ids = np.flatnonzero(filtered.reason == code)  # (K,)
        if len(env_ids):
            notices.append(Notice(kind, step, env_ids, "nonfinite_guard", reason))
    return notices


class Reports:
    """Statistics and events of the filter's commands, and the counts behind the rate line."""

    def __init__(
        self,
        emit: Callable[[Notice], None],
        clock: Callable[[], float],
        clip_event_period_s: float,
        stats_period_s: float,
        report_period_s: float,
    ) -> None:
        self.emit, self.clock = emit, clock
        self.clip_event_period_s = clip_event_period_s
        """At most one clip event per stage this often, s."""
        self.stats_period_s = stats_period_s
        self.stats = StatsAccumulator()
        self.clips: dict[str, tuple[StageStats, np.ndarray]] = {}
        """Per clip stage: stats and (B,) clipped environments since its last event."""
        self.last_clip_event: dict[str, float] = {}
        self.rate = LoopReport(report_period_s, self._line, logger=log, clock=clock)
        self.counts = self.rate.counts
        """What happened since the last rate line."""
        self.stopped_by: str | None = None
        self.env_transitions = 0
        """What stopped the loop and the trainer's counter, as of the last `periodic`."""
        self._last_stats = clock()

    def command(self, output: SafeOutput, latency: float) -> None:
        """Count one command, `latency` s after its state arrived."""
        self.counts["braked" if output.filtered is None else "tracked"] += 1
        self.rate.sample("latency_s", latency)

    def account(self, filtered: FilterResult, step: int) -> None:
        """Statistics, rejection events and (rate-limited) clip events of one command."""
        self.stats.add(filtered.reports)
        for notice in rejections(filtered, step):
            self.emit(notice)
        self.counts["rejected"] += int(filtered.rejected.sum())
        for report in filtered.reports:
            if report.stage in CLIP_KINDS:
                self._clip_event(report, step)

    def _clip_event(self, report: StageReport, step: int) -> None:
        """Count one clip stage's report; emit its event when it clipped and one is due."""
        stage = report.stage
        stats, envs = self.clips.get(stage, (empty_stats(stage), report.clipped))
        stats, envs = merge(stats, summarize(report)), envs | report.clipped  # (B,)
        self.clips[stage] = (stats, envs)
        now = self.clock()
        last = self.last_clip_event.get(stage, -np.inf)
        if not stats.clipped or now - last < self.clip_event_period_s:
            return
        reason = (
            f"clipped {stats.clipped} of {stats.commands} commands, "
            f"largest excess {stats.max_excess:.4g}"
        )
        self.emit(Notice(CLIP_KINDS[stage], step, np.flatnonzero(envs), stage, reason, (stats,)))
        self.last_clip_event[stage] = now
        del self.clips[stage]

    def periodic(
        self, step: int, env_ids: np.ndarray, stopped_by: str | None, env_transitions: int
    ) -> None:
        """Statistics event (about `env_ids` (B,), at state `step`) and rate line when due."""
        now = self.clock()
        if now - self._last_stats >= self.stats_period_s:
            summary = self.stats.summary()
            if any(s.commands for s in summary):
                reason = f"statistics over {now - self._last_stats:.1f} s"
                self.emit(Notice(STATISTICS, step, env_ids, "", reason, summary))
            self.stats.reset()
            self._last_stats = now
        self.stopped_by, self.env_transitions = stopped_by, env_transitions
        self.rate.tick()

    def _line(self, w: Window) -> str:
        c = w.count
        return (
            f"{w.rate('tracked', 'braked'):.1f} commands/s ({c('tracked')} tracking, "
            f"{c('braked')} braking), state->command median {w.median_ms('latency_s'):.1f} "
            f"ms, {c('rejected')} rejected, {c('stale')} stale and {c('ignored')} ignored "
            f"actions, {c('superseded')} superseded states, {c('watchdog')} watchdog stops, "
            f"{c('restarts')} sim restarts, {c('implausible')} implausible states, stopped "
            f"by {self.stopped_by or 'nothing'}, {self.env_transitions} env transitions"
        )
