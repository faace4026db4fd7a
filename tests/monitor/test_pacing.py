"""Frame pacing and the success rate, with hand-computed answers."""

from __future__ import annotations

import math

import numpy as np

from hamnet.monitor.pacing import REMEMBERED_STEPS, FramePacer, SuccessRate


def test_a_step_is_drawn_only_after_the_minimum_interval_and_its_messages_follow() -> None:
    pacer = FramePacer(min_interval_s=0.25)
    assert pacer.draw(0, now=10.0)
    assert not pacer.draw(1, now=10.125)  # too soon
    assert pacer.draw(0, now=10.1875)  # a later message of step 0 follows its decision
    assert not pacer.draw(1, now=10.5)  # ... and so does one of the skipped step 1
    assert pacer.draw(2, now=10.25)  # exactly the interval after step 0
    assert not pacer.draw(3, now=10.375)
    assert pacer.draw(4, now=10.5)
    assert (pacer.drawn, pacer.skipped) == (3, 2)


def test_decisions_are_forgotten_after_a_while() -> None:
    """A sim restarted from step 0 is drawn again once its old decisions are gone."""
    pacer = FramePacer(min_interval_s=1.0)
    for step in range(REMEMBERED_STEPS + 1):
        pacer.draw(step, now=float(step))
    assert pacer.draw(0, now=1000.0)  # step 0 was forgotten: decided again


def test_success_rate_over_the_last_episodes() -> None:
    rate = SuccessRate(window=3)
    assert math.isnan(rate.rate)
    assert rate.add(np.array([True, False, True]), np.array([True, True, False])) == 2
    assert rate.rate == 0.5  # success, failure (env 1 did not finish)
    rate.add(np.array([True, True, False]), np.array([True, True, False]))
    assert rate.rate == 2 / 3  # failure, success, success: the first success fell out
    assert rate.finished == 4
