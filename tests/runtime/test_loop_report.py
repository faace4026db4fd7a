"""The loop reporter on a hand-driven clock: one line per period, counts and samples of
that period only, figures into the health sink, nothing before a period has passed."""

from __future__ import annotations

import logging
import math

import pytest

from hamnet.runtime.loop_report import LoopReport, Window


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def reporter(clock: Clock, figures: dict[str, float] | None = None) -> LoopReport:
    return LoopReport(
        10.0,
        lambda w: f"{w.rate('steps'):.1f} steps/s, median {w.median_ms('step_s'):.1f} ms",
        figures=(lambda w: {"steps_per_s": w.rate("steps")}) if figures is not None else None,
        set_figure=figures.__setitem__ if figures is not None else None,
        clock=clock,
    )


def test_one_line_per_period_with_that_period_only(caplog: pytest.LogCaptureFixture) -> None:
    clock, figures = Clock(), {}
    report = reporter(clock, figures)
    caplog.set_level(logging.INFO, logger="hamnet.runtime.loop_report")
    for _ in range(20):
        report.sample("step_s", 0.002)
        assert report.tick(steps=1) is None  # no time has passed
    clock.now += 10.0
    window = report.tick(steps=0)
    assert window is not None and window.seconds == 10.0 and window.count("steps") == 20
    assert [r.getMessage() for r in caplog.records] == ["2.0 steps/s, median 2.0 ms"]
    assert figures == {"steps_per_s": 2.0}
    clock.now += 9.0
    assert report.tick(steps=5) is None  # the next period counts from the last line
    clock.now += 1.0
    window = report.tick()
    assert window.count("steps") == 5 and math.isnan(window.median_ms("step_s"))
    assert caplog.records[-1].getMessage() == "0.5 steps/s, median nan ms"


def test_counts_are_shared_in_place_and_cleared_per_window() -> None:
    clock = Clock()
    report = reporter(clock)
    counts = report.counts
    counts["stale"] += 2
    report.count("stale")
    clock.now += 10.0
    assert report.tick().count("stale") == 3
    assert counts is report.counts and counts["stale"] == 0


def test_flush_reports_what_is_there_and_restart_forgets_it() -> None:
    clock = Clock()
    report = reporter(clock)
    assert report.flush() is None  # no time has passed
    report.tick(steps=3)
    clock.now += 2.0
    assert report.flush() == Window(2.0, {"steps": 3}, {})
    report.tick(steps=3)
    clock.now += 4.0
    report.restart()
    clock.now += 10.0
    assert report.tick().count("steps") == 0


def test_running_totals_count_what_they_grew_by_in_the_window() -> None:
    clock = Clock()
    report = reporter(clock)
    report.total(drawn=7)  # what came before the first value is not this loop's
    report.total(drawn=10)
    clock.now += 10.0
    assert report.tick().count("drawn") == 3
    report.total(drawn=12)
    clock.now += 10.0
    assert report.tick().count("drawn") == 2


def test_bad_configuration_is_refused() -> None:
    with pytest.raises(ValueError, match="period_s"):
        LoopReport(0.0, str)
    with pytest.raises(ValueError, match="set_figure"):
        LoopReport(1.0, str, figures=lambda w: {})
