"""Episode records: the failure reason's precedence, validation and the JSON round trip."""

from __future__ import annotations

import itertools

import pytest

from hamnet.evaluation.records import (
    FAILURE_REASONS,
    EpisodeRecord,
    failure_reason,
    read_records,
    write_records,
)
from tests.evaluation.records import record

PRECEDENCE = ("success", "drop", "safety_stop", "collision", "torque_limit")
"""The documented order of `failure_reason`; timeout when none holds."""


@pytest.mark.parametrize("flags", list(itertools.product((False, True), repeat=5)))
def test_failure_reason_names_the_first_cause_in_precedence(flags: tuple[bool, ...]) -> None:
    """Every combination of the five flags (32) names the first one set in the documented
    precedence, and timeout when none is set; a swapped order fails some combination."""
    expected = next((name for name, flag in zip(PRECEDENCE, flags) if flag), "timeout")
    assert failure_reason(*flags) == expected


def test_failure_reasons_are_the_issues_five() -> None:
    assert FAILURE_REASONS == ("timeout", "drop", "safety_stop", "collision", "torque_limit")


def test_record_round_trips_through_dict_and_json_lines(tmp_path) -> None:
    """to_dict/from_dict and write/read_records give back equal records, in order."""
    records = [record("sink"), record("procedural", "drop", 40, pair=3)]
    assert [EpisodeRecord.from_dict(r.to_dict()) for r in records] == records
    assert read_records(write_records(tmp_path / "episodes.jsonl", records)) == records


@pytest.mark.parametrize(
    "change",
    [
        {"suite": "kitchen"},
        {"reason": "exploded"},
        {"success": False},  # reason stays "success"
        {"length": -1},
    ],
)
def test_record_rejects_inconsistent_fields(change: dict) -> None:
    """A typo in a suite or reason, or success contradicting the reason, fails at once."""
    with pytest.raises(ValueError):
        EpisodeRecord(**{**record("sink").to_dict(), **change})
