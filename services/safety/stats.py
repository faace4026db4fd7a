"""Per-stage statistics: which environments a stage changed and by how much.

Each filter call yields one `StageReport` per stage, per environment (B,). `StageStats`
summarises reports as the SafetyEvent's StageStats message does (commands, clipped, mean and
max excess), and `StatsAccumulator` sums them between two publications, so a user sees why the
robot moved less than the policy asked.

Excess units per stage: nonfinite_guard 1 per rejected action; action_magnitude rad of
residual removed (largest joint); cartesian_clip ||J dq|| - eps_x (m); residual_smoothing rad
changed by the EMA (largest joint); joint_limits rad of target removed (largest joint);
torque_preclip N m of predicted torque above the limit (largest joint).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STAGE_NAMES = (
    "nonfinite_guard",
    "action_magnitude",
    "cartesian_clip",
    "residual_smoothing",
    "joint_limits",
    "torque_preclip",
)
"""The core's stages in order (stage 6, trajectory, runs outside the core after joint_limits)."""


@dataclass(frozen=True)
class StageReport:
    """What one stage did to each environment in one filter call."""

    stage: str
    """Stage name, one of STAGE_NAMES."""
    applied: np.ndarray
    """(B,) bool, the environment's command went through the stage (enabled, not rejected)."""
    clipped: np.ndarray
    """(B,) bool, the stage changed the command (always within `applied`)."""
    excess: np.ndarray
    """(B,) float, how much it removed in the stage's unit (module docstring); 0 if unchanged."""


def stage_report(stage: str, applied: np.ndarray, excess: np.ndarray) -> StageReport:
    """A report where `clipped` means a positive excess on an applied environment.

    Excesses are capped at the float64 maximum so that statistics stay finite (an infinite
    predicted torque from an absurd joint speed still counts, as the largest number)."""
    excess = np.where(applied, np.minimum(excess, np.finfo(np.float64).max), 0.0)  # (B,)
    clipped = applied & (excess > 0.0)
    return StageReport(stage=stage, applied=applied, clipped=clipped, excess=excess)


@dataclass(frozen=True)
class StageStats:
    """Summary of one stage over some commands (the StageStats message)."""

    stage: str
    """Stage name."""
    commands: int
    """Environment commands that went through the stage."""
    clipped: int
    """Of those, how many it changed."""
    mean_excess: float
    """Mean excess over the changed commands (0 when none)."""
    max_excess: float
    """Largest excess (0 when none)."""


def summarize(report: StageReport) -> StageStats:
    """StageStats of one report."""
    excess = report.excess[report.clipped]  # (K,)
    clipped = int(excess.size)
    return StageStats(
        stage=report.stage,
        commands=int(np.count_nonzero(report.applied)),
        clipped=clipped,
        # Dividing first keeps the mean finite for excesses near the float64 maximum.
        mean_excess=float(np.sum(excess / clipped)) if clipped else 0.0,
        max_excess=float(excess.max()) if clipped else 0.0,
    )


def merge(first: StageStats, second: StageStats) -> StageStats:
    """Stats of the union of the commands behind `first` and `second` (same stage)."""
    clipped = first.clipped + second.clipped
    mean = 0.0
    if clipped:  # weights first: a plain sum of two near-maximal means would overflow
        mean = first.mean_excess * (first.clipped / clipped)
        mean += second.mean_excess * (second.clipped / clipped)
    return StageStats(
        stage=first.stage,
        commands=first.commands + second.commands,
        clipped=clipped,
        mean_excess=mean,
        max_excess=max(first.max_excess, second.max_excess),
    )


def empty_stats(stage: str) -> StageStats:
    """Stats of no commands."""
    return StageStats(stage=stage, commands=0, clipped=0, mean_excess=0.0, max_excess=0.0)


class StatsAccumulator:
    """Running StageStats per stage since the last `reset` (e.g. the last published event)."""

    def __init__(self) -> None:
        self._stats = {name: empty_stats(name) for name in STAGE_NAMES}

    def add(self, reports: tuple[StageReport, ...]) -> None:
        """Count one filter call's reports."""
        for report in reports:
            self._stats[report.stage] = merge(self._stats[report.stage], summarize(report))

    def summary(self) -> tuple[StageStats, ...]:
        """Current stats, in STAGE_NAMES order."""
        return tuple(self._stats[name] for name in STAGE_NAMES)

    def reset(self) -> None:
        """Start counting afresh."""
        self._stats = {name: empty_stats(name) for name in STAGE_NAMES}
