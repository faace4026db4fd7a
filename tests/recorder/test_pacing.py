"""Replay's pure parts: namespace remapping, recorded time to wall time, step grouping,
stdin step requests and topic filters."""

from __future__ import annotations

import pytest

from hamnet.recorder.pacing import group_steps, remap_key
from hamnet.recorder.replay_shell import QUIT, parse_step_request, step_of
from hamnet.runtime.recordings import RecordedMessage, ReplayClock, selected
from tests.recorder.recordings import RAW, STATE, T0, TRANSITION, lock_step


def test_keys_move_into_the_replay_namespace_and_others_stay() -> None:
    assert remap_key("hamnet/live/sim/0/state", "replayed") == "hamnet/replayed/sim/0/state"
    assert remap_key("hamnet/live/trainer/weights", "live") == "hamnet/live/trainer/weights"
    assert remap_key("robot/joint_states", "replayed") == "robot/joint_states"
    with pytest.raises(ValueError, match="namespace"):
        remap_key("hamnet/live/sim/0/state", "a/b")


def test_clock_scales_recorded_time_by_the_speed() -> None:
    clock = ReplayClock(first_log_ns=T0, start_s=100.0, speed=4.0)
    assert clock.due_s(T0) == 100.0
    assert clock.due_s(T0 + 2_000_000_000) == pytest.approx(100.5)


def test_a_step_runs_from_a_new_marker_to_the_next_and_repeats_stay_inside() -> None:
    # (name, marker step): preamble, marker 0, its repeat, marker 1, marker 3, stale marker 2
    items = [("scene", None), ("s0", 0), ("a", None), ("s0 again", 0), ("t0", None),
             ("s1", 1), ("t1", None), ("s3", 3), ("s2 late", 2), ("t3", None)]  # fmt: skip
    groups = list(group_steps(items, lambda item: item[1]))
    assert [[name for name, _ in g] for g in groups] == [
        ["scene", "s0", "a", "s0 again", "t0"], ["s1", "t1"], ["s3", "s2 late", "t3"]
    ]
    assert list(group_steps([], lambda item: None)) == []
    assert list(group_steps(["x", "y"], lambda item: None)) == [["x", "y"]]


def test_states_mark_steps_in_a_recorded_lock_step_run() -> None:
    messages = [RecordedMessage(k, p, t, t, "") for k, p, t in lock_step(4)]
    assert [step_of(m) for m in messages if m.key == STATE] == [0, 0, 1, 2, 3]
    assert {step_of(m) for m in messages if m.key != STATE} == {None}
    groups = list(group_steps(messages, step_of))
    assert [len(g) for g in groups] == [4, 3, 3, 3]
    garbage = RecordedMessage(STATE, b"\xff\xff", T0, T0, "")
    assert step_of(garbage) is None


def test_stdin_step_requests() -> None:
    assert [parse_step_request(s) for s in ("\n", "3\n", " q ", "quit", "x", "0", "-2")] == [
        1, 3, QUIT, QUIT, None, None, None
    ]


def test_topic_filters_are_zenoh_key_expressions() -> None:
    messages = [RecordedMessage(k, p, t, t, "") for k, p, t in lock_step(2)]
    keys = lambda topics: [m.key for m in selected(messages, topics)]  # noqa: E731
    assert keys(()) == [m.key for m in messages]
    assert set(keys(("hamnet/*/sim/**",))) == {STATE, TRANSITION}
    assert set(keys(("hamnet/rec/custom/raw", "hamnet/**/transition"))) == {RAW, TRANSITION}
    assert keys(("nothing/**",)) == []
