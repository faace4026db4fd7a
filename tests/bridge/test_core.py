"""The bridge's core without Zenoh: the safety filter's 1 kHz references run on the strict
fake FR3 without a reflex; a NaN or out-of-limit command never reaches the driver and stops
the stream; any robot error (reflex, deadline, lost connection) stops the stream until an
explicit reset, which starts a new episode at the measured positions."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hamnet.bridge.core import BridgeCommand, BridgeCore, encode_state
from hamnet.bridge.driver import COMMAND_REJECTED, CONNECTION_LOST, DEADLINE_MISSED
from hamnet.bridge.fake import FakeDriver, FakeDriverConfig
from hamnet.fr3.limits import FR3, Q_HOME
from hamnet.messages.safe_command import hold_command
from hamnet.runtime.tensor import from_tensor
from tests.bridge.driving import drive
from tests.clock import Clock

PERIOD = 0.1


def make(deadline_s: float = 1.0) -> tuple[BridgeCore, FakeDriver, Clock]:
    clock = Clock()
    driver = FakeDriver(FakeDriverConfig(deadline_s), Q_HOME, clock)
    return BridgeCore(driver, PERIOD), driver, clock


def test_safe_commands_run_on_the_strict_fake_without_a_reflex() -> None:
    core, driver, _ = make()
    assert drive(core, 200) == [] and core.streaming
    assert driver.sent == core.counts["executed"] == 200
    assert int(driver.robot.ticks[0]) == 200 * core.samples
    assert np.abs(driver.read().q - Q_HOME).max() > 0.05  # the arm moved


@pytest.mark.parametrize("bad", ["nan", "beyond_limit", "jump", "torque_limit"])
def test_a_bad_command_never_reaches_the_driver_and_stops_the_stream(bad: str) -> None:
    core, driver, _ = make()
    command = hold_command(Q_HOME[None], core.samples)
    q_ref = command.q_ref.copy()
    if bad == "nan":
        q_ref[0, 5, 2] = np.nan
    elif bad == "beyond_limit":
        q_ref[0, :, 3] = FR3.q_max[3] + 0.01
    elif bad == "jump":
        q_ref[0, 10:, 0] += 0.01
    command = dataclasses.replace(command, q_ref=q_ref)
    if bad == "torque_limit":
        command = dataclasses.replace(command, tau_limit=command.tau_limit + 1.0)
    errors = core.execute(BridgeCommand(0, 0, command), 0)
    assert [e.name for e in errors] == [COMMAND_REJECTED] and not core.streaming
    assert driver.sent == 0 and int(driver.robot.ticks[0]) == 0
    good = hold_command(Q_HOME[None], core.samples)
    assert core.execute(BridgeCommand(1, 0, good), 1) == [] and driver.sent == 0  # stopped
    assert core.counts["refused"] == 1


def test_a_reflex_stops_the_stream_until_an_explicit_reset() -> None:
    core, driver, _ = make()
    assert drive(core, 20) == []
    reading = core.read()
    loose = {name: getattr(FR3, name) * 1e9 for name in ("dq_max", "ddq_max", "jerk_max")}
    core.limits = dataclasses.replace(FR3, **loose)  # the pre-check lets a jump through
    jump = hold_command(reading.q[None] + 0.05, core.samples)
    errors = core.execute(BridgeCommand(20, 0, jump), 20)
    assert errors and not core.streaming and driver.robot.in_reflex[0]
    assert {e.name for e in errors} & {"joint_motion_generator_velocity_limits_violation"}
    core.limits = FR3
    assert np.all(core.read().dq == 0)  # the arm rests
    assert core.execute(BridgeCommand(21, 0, hold_command(reading.q[None], core.samples)), 21) == []
    assert core.counts["refused"] == 1
    reading = core.reset()
    assert core.streaming and core.episode_id == 1 and not driver.robot.in_reflex[0]
    old = hold_command(reading.q[None], core.samples)
    assert core.execute(BridgeCommand(22, 0, old), 22) == [] and core.counts["stale"] == 1
    assert drive(core, 20, seed=1, first=23) == [] and core.streaming


def test_a_missed_deadline_and_a_lost_connection_stop_the_robot() -> None:
    core, driver, clock = make(deadline_s=0.5)
    assert drive(core, 5) == []
    clock.now = 0.4
    assert core.poll() == []
    clock.now = 0.6
    assert [e.name for e in core.poll()] == [DEADLINE_MISSED] and not core.streaming
    assert np.all(core.read().dq == 0)
    core.reset()
    assert drive(core, 5, first=10) == []
    driver.disconnect()
    assert [e.name for e in core.poll()] == [CONNECTION_LOST] and core.read() is None
    assert core.reset() is not None and core.streaming and core.episode_id == 2


def test_the_state_has_the_sims_fields_but_no_privileged_block() -> None:
    core, _, _ = make()
    message = encode_state(core.read(), 7, 3, 2, np.array([0.5, 0, 0.1, 1, 0, 0, 0]))
    assert not message.HasField("privileged") and message.header.step == 7
    ee_pos_rot6d = from_tensor(message.ee_pos_rot6d, np.float32, (1, 9))
    assert np.allclose(ee_pos_rot6d[0, :3], [0.50, 0.0, 0.455], atol=0.01)  # Q_HOME's pose
    assert np.allclose(ee_pos_rot6d[0, 3:], [1, 0, 0, 0, -1, 0], atol=1e-4)  # paddle face down
    assert from_tensor(message.episode_ids, np.int64, (1,)).tolist() == [3]


def test_a_reset_that_cannot_reach_the_robot_says_why_and_a_later_one_streams_again() -> None:
    """The robot off the network: the reset keeps the stream stopped and the reason, instead
    of raising out of the bridge; once it is back, a reset streams again."""
    core, driver, _ = make()
    assert drive(core, 5) == []
    driver.disconnect(reachable=False)
    assert [e.name for e in core.poll()] == [CONNECTION_LOST]
    assert core.reset() is None and not core.streaming
    assert "cannot reach" in core.reset_failure and core.episode_id == 0
    driver.reachable = True
    assert core.reset() is not None and core.streaming and core.reset_failure == ""
    assert drive(core, 5, first=5) == [] and core.streaming


def test_a_command_stamped_ahead_of_the_newest_state_is_refused_and_blinds_nothing() -> None:
    """A hold command stamped 10^12 would make every genuine command after it stale: it
    answers no state the bridge published, so it is refused; and a reset starts the
    episode's steps afresh."""
    core, driver, _ = make()
    hold = hold_command(Q_HOME[None], core.samples)
    for step in range(5):
        assert core.execute(BridgeCommand(step, 0, hold), step) == []
    assert core.execute(BridgeCommand(10**12, 0, hold), 5) == []
    assert core.counts["ahead"] == 1 and driver.sent == 5 and core.last_step == 4
    for step in range(5, 10):
        assert core.execute(BridgeCommand(step, 0, hold), step) == []
    assert core.counts["executed"] == 10 and core.counts["stale"] == 0
    core.stop("test")
    core.reset()
    assert core.last_step == -1
    assert drive(core, 3, first=0) == [] and core.counts["executed"] == 13
