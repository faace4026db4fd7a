"""The step watermark across producer restarts (`hamnet.runtime.freshness`)."""

from __future__ import annotations

import pytest

from hamnet.runtime.freshness import Answered, Verdict, Watermark


def test_steps_of_one_run_are_fresh_repeated_or_stale() -> None:
    mark = Watermark(max_jump=100)
    assert mark.judge(5, 40) is Verdict.RESTART  # the first message: follow its run
    assert not mark.restart(5)  # nothing was followed before
    assert mark.judge(5, 40) is Verdict.FRESH and mark.judge_step(3) is Verdict.FRESH
    mark.advance(40)
    assert [mark.judge(5, k) for k in (39, 40, 41, 140, 141)] == [
        Verdict.STALE, Verdict.REPEAT, Verdict.FRESH, Verdict.FRESH, Verdict.IMPLAUSIBLE,
    ]  # fmt: skip
    assert mark.judge_step(41) is Verdict.FRESH and mark.judge_step(39) is Verdict.STALE


def test_another_run_restarts_whatever_its_step() -> None:
    """A restarted producer counts from 0: its steps are not stale, and a message of the old
    run after that restarts again (no run is retired: a forger's run would shut out the real
    producer for good)."""
    mark = Watermark()
    mark.restart(5)
    mark.advance(10**6)
    assert mark.judge(6, 0) is Verdict.RESTART
    assert mark.restart(6)
    assert mark.run == 6 and mark.step is None and mark.judge(6, 0) is Verdict.FRESH
    mark.advance(0)
    assert mark.judge(5, 10**6 + 1) is Verdict.RESTART


def test_a_far_future_step_leaves_the_watermark_where_it_was() -> None:
    mark = Watermark(max_jump=10)
    mark.restart(1)
    mark.advance(3)
    assert mark.judge(1, 10**12) is Verdict.IMPLAUSIBLE
    assert (mark.run, mark.step) == (1, 3) and mark.judge(1, 4) is Verdict.FRESH
    mark.advance(2)  # a late state acted on (the safety filter answers those too)
    assert mark.step == 3


def test_max_jump_must_be_positive() -> None:
    with pytest.raises(ValueError, match="max_jump"):
        Watermark(max_jump=0)


def test_an_answer_is_sent_again_for_its_step_and_dropped_when_the_producer_restarts() -> None:
    """The policy and perception answer the sim's states the same way (`Answered`): the first
    message is fresh, its repeat gets the same answer, an older step is stale, and another run
    is a restart that forgets the old run's answer."""
    answered: Answered[str] = Answered(Watermark(max_jump=10))
    assert answered.follow(5, 40) is Verdict.FRESH  # the very first message: no restart
    answered.answer(40, "a40")
    assert answered.follow(5, 40) is Verdict.REPEAT and answered.message == "a40"
    assert answered.follow(5, 39) is Verdict.STALE
    assert answered.follow(5, 10**12) is Verdict.IMPLAUSIBLE
    assert answered.follow(6, 40) is Verdict.RESTART and answered.message is None
    assert answered.follow(6, 40) is Verdict.FRESH
