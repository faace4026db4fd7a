"""The bridge's shell on real Zenoh with the strict fake FR3 in this process: a reset that
cannot reach the robot answers why and leaves the bridge up, the next one streams again;
a command stamped far ahead never blinds the bridge; the pacing follows a robot clock that
goes back instead of waiting for it."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from types import SimpleNamespace

import numpy as np
import pytest

from hamnet.bridge.core import BridgeCore
from hamnet.bridge.fake import FakeDriver
from hamnet.bridge.loop import BridgeLoopConfig, paced
from hamnet.bridge.shell import BridgeShell
from hamnet.messages import robot_state, safe_command
from hamnet.messages.safe_command import hold_command
from hamnet.proto.safety_pb2 import CommandMode
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.runtime.transport import TransportConfig, open_session
from tests.estop import ask_estop

PERIOD = 0.05


@pytest.fixture
def bridge(transport: TransportConfig) -> Iterator[tuple[FakeDriver, BridgeShell, Inbox, Callable]]:
    """A running bridge shell on the fake FR3; yields the driver, the shell, an inbox of its
    states and `ask(command)` for its reset queryable."""
    driver = FakeDriver()
    core = BridgeCore(driver, PERIOD)
    with Service(ServiceIdentity("bridge", "0"), transport) as service:
        shell = BridgeShell(service, core, BridgeLoopConfig(policy_period_s=PERIOD))
        thread = threading.Thread(target=shell.run, daemon=True)
        session = open_session(transport)
        inbox = Inbox(session, DropCounter())
        ns = transport.namespace
        inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
        key = contract.topic("bridge/<w>/reset").key(ns, w="0")
        thread.start()
        try:
            yield driver, shell, inbox, lambda command: ask_estop(session, key, command)
        finally:
            service.stop()
            thread.join(10)
            session.close()
        assert not thread.is_alive()


def until(predicate: Callable[[], object], what: str, deadline_s: float = 20.0) -> object:
    """Poll `predicate` until it returns something true; fail with `what` past the deadline."""
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        if value := predicate():
            return value
        time.sleep(0.05)
    raise AssertionError(f"not within {deadline_s} s: {what}")


def next_state(inbox: Inbox) -> RobotState:
    received = until(lambda: inbox.get(timeout=0.5), "a state")
    return received.value


def test_a_reset_the_robot_cannot_answer_leaves_the_bridge_up_and_says_why(bridge) -> None:
    driver, shell, inbox, ask = bridge
    next_state(inbox)
    driver.disconnect(reachable=False)
    until(lambda: ask("status")["errors"] == ["connection_lost"], "the lost link reported")
    ask("reset")
    failed = until(lambda: ask("status")["last_reset"], "the reset's outcome")
    assert failed["ok"] is False and "cannot reach" in failed["reason"]
    assert ask("status")["streaming"] is False and shell.resets.resetting is None
    driver.reachable = True
    ask("reset")
    until(lambda: (ask("status")["last_reset"] or {}).get("ok"), "a reset that streams")
    assert ask("status")["streaming"] is True
    episode = lambda: int(robot_state.decode(next_state(inbox)).episode_ids[0])
    until(lambda: episode() == 1, "states of the new episode")


def command(hold, step: int, shell: BridgeShell):
    """SafeCommand `step` holding the arm, for the bridge's current episode."""
    episode = np.array([shell.core.episode_id])
    references = SimpleNamespace(**vars(hold), dq_ref=np.zeros_like(hold.q_ref))
    return safe_command.encode(references, step, CommandMode.HOLD, episode,
                               shell.core.driver.control_period_s)  # fmt: skip


def test_a_command_stamped_far_ahead_leaves_the_genuine_ones_executed(bridge, transport) -> None:
    driver, shell, inbox, ask = bridge
    session = open_session(transport)
    commands = Publisher(session, contract.topic("safety/<w>/command").key(transport.namespace, w="0"),
                         "safety/0")  # fmt: skip
    try:
        state = next_state(inbox)
        hold = hold_command(driver.read().q[None], shell.core.samples)
        commands.put(command(hold, 10**12, shell))
        until(lambda: shell.core.counts["ahead"] == 1, "the forged command refused")
        for _ in range(3):
            state = next_state(inbox)
            commands.put(command(hold, state.header.step, shell))
        until(lambda: shell.core.counts["executed"] >= 2, "genuine commands executed")
        assert ask("status")["streaming"] is True and shell.core.last_step < 10**12
    finally:
        session.close()


@pytest.mark.parametrize(
    ("tick", "now", "expected"),
    [(10.0, 10.0, 10.0), (10.0, 10.04, 10.0), (10.0, 10.2, 10.2), (10.0, 3.0, 3.0)],
)
def test_the_pace_restarts_from_a_clock_that_fell_behind_or_went_back(tick, now, expected) -> None:
    """Within a period the schedule holds; a loop a period late does not burst to catch up,
    and a clock that went back (a reconnected robot's) is followed, not waited for."""
    assert paced(tick, now, PERIOD) == expected
