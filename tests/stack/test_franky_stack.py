"""`hamnet bridge --driver franky` on franky-sim (the libfranka protocol on loopback) and
`hamnet safety` as processes on real Zenoh, with this test as the policy: random actions
for hundreds of policy steps without a robot error; a NaN action is rejected by safety and
never reaches the robot; when the policy stops answering, the watchdog brings the arm to
rest within a second; the bridge reports its state-to-command latency in health."""

from __future__ import annotations

import time

import numpy as np

from hamnet.proto.common_pb2 import Header
from hamnet.proto.health_pb2 import Health
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafetyEvent, SafetyEventKind
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import from_tensor, to_tensor
from hamnet.runtime.transport import open_session
from tests.conftest import transport_args
from tests.franky_sim import franky_sim

PERIOD = 0.05
ACTING, NAN_AT = 300, 150
"""Steps the test answers, and the one answered with a NaN action."""
REST_WITHIN_S = 1.5
"""The watchdog (0.3 s) plus the brake's ramp to rest, on this machine's clock: franky-sim
steps in Python and runs at about 0.67x real time on 2 loaded cores, so 1 s of the robot
takes 1.5 s here (1.0 s once left the arm at 0.0115 rad/s, still slowing, in a fresh clone)."""


def test_a_policy_drives_franky_sim_through_safety_and_stops_when_it_dies(spawn, transport) -> None:
    with franky_sim() as (host, _):
        # franky-sim steps in Python: on 2 loaded cores its clock can stall past the 0.1 s
        # that means a lost link on a real FR3, so this test allows it a second.
        robot = ["--driver", "franky", "--franky.host", host, "--franky.realtime", "ignore",
                 "--franky.link-timeout-s", "1.0"]  # fmt: skip
        bridge = spawn(
            "bridge", *robot, "--policy-period-s", str(PERIOD), *transport_args(transport)
        )
        safety = spawn("safety", "--num-envs", "1", "--trajectory.policy-period-s", str(PERIOD),
                       "--trajectory.control-rate-hz", "1000", *transport_args(transport))  # fmt: skip
        ns = transport.namespace
        session = open_session(transport)
        inbox = Inbox(session, DropCounter())
        inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
        inbox.subscribe("robot", contract.topic("bridge/<w>/event").key(ns, w="0"), SafetyEvent)
        inbox.subscribe("safety", contract.topic("safety/<w>/event").key(ns, w="0"), SafetyEvent)
        health = contract.topic("health/<service>/<w>").key(ns, service="bridge", w="0")
        inbox.subscribe("health", health, Health)
        actions = Publisher(session, contract.topic("policy/<w>/action").key(ns, w="0"), "policy/0")
        rng = np.random.default_rng(0)
        events: dict[str, list] = {"robot": [], "safety": [], "health": []}
        trace: list[tuple[float, np.ndarray]] = []  # (time, q) of each state
        answered, died = 0, None
        started = time.monotonic()
        try:
            while died is None or time.monotonic() - died < REST_WITHIN_S + 1.0:
                for process in (bridge, safety):
                    assert process.poll() is None, process.stdout.read()
                assert time.monotonic() - started < 90, f"{answered} answered, {events}"
                received = inbox.get(timeout=0.5)
                if received is None:
                    continue
                if received.name != "state":
                    events[received.name].append(received.value)
                    continue
                state = received.value
                trace.append((time.monotonic(), from_tensor(state.q, np.float32, (1, 7))[0]))
                if answered == ACTING:
                    died = died or time.monotonic()
                    continue
                action = np.clip(0.5 * rng.standard_normal((1, 21)), -1, 1).astype(np.float32)
                if answered == NAN_AT:
                    action[0, 3] = np.nan
                message = PolicyAction(header=Header(step=state.header.step))
                to_tensor(action, message.action)
                actions.put(message)
                answered += 1
        finally:
            session.close()
    assert events["robot"] == [], [(e.kind, e.reason) for e in events["robot"]]
    figures = [h.figures for h in events["health"] if "command_latency_p99_ms" in h.figures]
    assert figures, "the bridge reported no command latency"
    assert 0.0 < figures[-1]["command_latency_median_ms"] <= figures[-1]["command_latency_p99_ms"]
    kinds = [e.kind for e in events["safety"]]
    assert SafetyEventKind.REJECTED_NONFINITE in kinds and SafetyEventKind.WATCHDOG_STOP in kinds
    times = np.array([t for t, _ in trace])
    q = np.stack([q for _, q in trace])
    speed = np.abs(np.diff(q, axis=0)).max(axis=1) / np.diff(times)  # (N-1,) rad/s, fastest joint
    acting = times[1:] < died
    assert speed[acting].max() > 0.05, "the arm did not follow the policy"
    assert speed[times[1:] > died + REST_WITHIN_S].max() < 0.01, "the arm did not come to rest"


def test_a_dead_robot_is_one_error_event_and_the_bridge_stays_up(spawn, transport) -> None:
    with franky_sim() as (host, robot):
        bridge = spawn("bridge", "--franky.host", host, "--franky.realtime", "ignore",
                       "--policy-period-s", str(PERIOD), *transport_args(transport))  # fmt: skip
        session = open_session(transport)
        try:
            inbox = Inbox(session, DropCounter())
            ns = transport.namespace
            inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
            inbox.subscribe("robot", contract.topic("bridge/<w>/event").key(ns, w="0"), SafetyEvent)
            started = time.monotonic()
            while (received := inbox.get(timeout=0.5)) is None or received.name != "state":
                assert bridge.poll() is None and time.monotonic() - started < 60, (
                    bridge.stdout.read()
                )
            robot.kill()
            errors: list[str] = []
            while not errors and time.monotonic() - started < 90:
                received = inbox.get(timeout=0.5)
                if received is not None and received.name == "robot":
                    errors.append(received.value.reason)
            assert errors and errors[0].startswith("connection_lost"), errors
            time.sleep(1.0)
            assert bridge.poll() is None, bridge.stdout.read()  # it waits for a reset
        finally:
            session.close()
