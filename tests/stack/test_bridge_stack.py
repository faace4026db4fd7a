"""`hamnet bridge --driver fake` and `hamnet safety` as processes on real Zenoh, with this
test as the policy: a few hundred policy steps of random actions at 1 kHz references on the
strict fake FR3 without a robot error; then an operator `stop` on the bridge's reset
queryable stops the stream (a ROBOT_ERROR event) until `reset` (ROBOT_RESET), after which
the arm follows the policy again."""

from __future__ import annotations

import time

import numpy as np

from hamnet.proto.common_pb2 import Header
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafetyEvent, SafetyEventKind
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import from_tensor, to_tensor
from hamnet.runtime.transport import open_session
from tests.conftest import transport_args
from tests.estop import ask_estop

PERIOD = "0.05"
STEPS = 300
STOP_AT, RESET_AT = 200, 210


def test_policy_drives_the_fake_fr3_through_safety_and_the_bridge(spawn, transport) -> None:
    bridge = spawn("bridge", "--driver", "fake", "--policy-period-s", PERIOD,
                   *transport_args(transport))  # fmt: skip
    safety = spawn("safety", "--num-envs", "1", "--trajectory.policy-period-s", PERIOD,
                   "--trajectory.control-rate-hz", "1000", *transport_args(transport))  # fmt: skip
    ns = transport.namespace
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
    inbox.subscribe("event", contract.topic("bridge/<w>/event").key(ns, w="0"), SafetyEvent)
    actions = Publisher(session, contract.topic("policy/<w>/action").key(ns, w="0"), "policy/0")
    reset_key = contract.topic("bridge/<w>/reset").key(ns, w="0")
    rng = np.random.default_rng(0)
    events: list[tuple[int, int, str]] = []
    speeds: dict[int, float] = {}
    episodes: dict[int, int] = {}
    started = time.monotonic()
    count = 0
    try:
        while count < STEPS:
            for process in (bridge, safety):
                assert process.poll() is None, process.stdout.read()
            assert time.monotonic() - started < 50, f"{count} states, events {events}"
            received = inbox.get(timeout=0.5)
            if received is None:
                continue
            if received.name == "event":
                e = received.value
                events.append((count, e.kind, e.reason))
                continue
            state = received.value
            assert not state.HasField("privileged")
            count += 1
            speeds[count] = float(np.abs(from_tensor(state.dq, np.float32, (1, 7))).max())
            episodes[count] = int(from_tensor(state.episode_ids, np.int64, (1,))[0])
            if count == STOP_AT:
                assert ask_estop(session, reset_key, "stop")["latched"] is True
            if count == RESET_AT:
                assert ask_estop(session, reset_key, "reset")["latched"] is False
            action = np.clip(0.5 * rng.standard_normal((1, 21)), -1, 1).astype(np.float32)
            message = PolicyAction(header=Header(step=state.header.step))
            to_tensor(action, message.action)
            actions.put(message)
    finally:
        session.close()
    errors = [(n, r) for n, k, r in events if k == SafetyEventKind.ROBOT_ERROR]
    resets = [n for n, k, _ in events if k == SafetyEventKind.ROBOT_RESET]
    assert len(errors) == 1 and errors[0][1].startswith("stop_requested"), events
    assert STOP_AT <= errors[0][0] <= RESET_AT and len(resets) == 1, events
    assert max(speeds[n] for n in range(10, STOP_AT)) > 0.05  # the arm followed the policy
    assert episodes[STOP_AT] == 0 and episodes[STEPS] == 1  # the reset began an episode
    assert max(speeds[n] for n in range(RESET_AT + 20, STEPS + 1)) > 0.05  # and it follows again
