"""The bridge's command timing (`hamnet.bridge.loop.CommandLatency`), moved out of its shell."""

from __future__ import annotations

import pytest

from hamnet.bridge.loop import LATENCY_HORIZON, CommandLatency


def test_each_command_is_timed_once_from_its_states_publication() -> None:
    """State 0 went out at t = 1 s and its command ran at 1.02 s: 20 ms; a second command for
    the same state, or one for a state older than LATENCY_HORIZON, is not timed."""
    latency = CommandLatency()
    assert latency.figures() == {}
    latency.published_state(0, 1.0)
    latency.published_state(1, 1.1)
    latency.executed(0, 1.02)
    latency.executed(0, 1.5)  # timed already
    for step in range(2, 2 + LATENCY_HORIZON):
        latency.published_state(step, 2.0)
    latency.executed(1, 9.0)  # its state left the horizon
    figures = latency.figures()
    assert figures["command_latency_count"] == 1
    assert figures["command_latency_median_ms"] == pytest.approx(20.0)
    assert figures["command_latency_p99_ms"] == pytest.approx(20.0)
