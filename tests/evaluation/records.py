"""Synthetic episode records for the evaluation tests (no sim)."""

from __future__ import annotations

from hamnet.evaluation.records import SUCCESS, EpisodeRecord


def record(suite: str, reason: str = SUCCESS, length: int = 100, pair: int = 0) -> EpisodeRecord:
    """One episode of `suite` that ended with `reason` after `length` steps."""
    return EpisodeRecord(
        suite=suite,
        object_name="bulldozer",
        pair=pair,
        init=0,
        success=reason == SUCCESS,
        reason=reason,
        length=length,
        start_distance=0.3,
        final_distance=0.01 if reason == SUCCESS else 0.2,
        final_angle=0.05 if reason == SUCCESS else 1.0,
    )
