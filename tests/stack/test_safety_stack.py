"""`hamnet sim` and `hamnet safety` as processes on real Zenoh, with this test as the policy.

The test publishes a small random action for each state; the sim steps in lock-step on the
safety's commands. A NaN action becomes a REJECTED_NONFINITE event while the states stay
finite; the e-stop queryable latches a stop (commands turn to STOP although actions keep
coming) and resets it; then the policy dies (no more actions): a WATCHDOG_STOP event arrives
and the sim's arm comes to rest within a second of it.
"""

from __future__ import annotations

import time

import numpy as np

from hamnet.proto.common_pb2 import Header
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import CommandMode, SafeCommand, SafetyEvent, SafetyEventKind
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import from_tensor, to_tensor
from hamnet.runtime.transport import open_session
from tests.conftest import transport_args
from tests.estop import ask_estop

B, J = 2, 7
WATCHDOG_S = 0.3
REST_DQ = 0.02
"""rad/s: every joint of every arm slower than this is at rest."""


def test_policy_to_sim_through_safety_with_nan_estop_and_watchdog(spawn, transport) -> None:
    sim = spawn("sim", "--num-envs", str(B), "--num-objects", "2", "--nthread", "1",
                "--resend-s", "0.2", *transport_args(transport))  # fmt: skip
    safety = spawn("safety", "--num-envs", str(B), "--watchdog-s", str(WATCHDOG_S),
                   "--stats-period-s", "1", *transport_args(transport))  # fmt: skip
    ns = transport.namespace
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
    inbox.subscribe("command", contract.topic("safety/<w>/command").key(ns, w="0"), SafeCommand)
    inbox.subscribe("event", contract.topic("safety/<w>/event").key(ns, w="0"), SafetyEvent)
    actions = Publisher(session, contract.topic("policy/<w>/action").key(ns, w="0"), "policy/0")
    estop_key = contract.topic("safety/<w>/estop").key(ns, w="0")
    rng = np.random.default_rng(0)
    events: list[SafetyEvent] = []
    commands: dict[int, SafeCommand] = {}
    dq_max: dict[int, float] = {}
    phase, nan_step, estop_steps, dead_since = "policy", None, {}, None
    rested_at = None
    started = time.monotonic()
    try:
        while rested_at is None:
            for process in (sim, safety):
                assert process.poll() is None, process.stdout.read()
            if time.monotonic() - started > 30:
                for process in (sim, safety):
                    process.terminate()
                logs = sim.communicate()[0] + safety.communicate()[0]
                raise AssertionError(f"stuck in phase {phase} after {len(dq_max)} states\n{logs}")
            received = inbox.get(timeout=0.5)
            if received is None:
                continue
            if received.name == "event":
                events.append(received.value)
                continue
            if received.name == "command":
                commands[received.value.header.step] = received.value
                continue
            state = received.value
            step = state.header.step
            dq = from_tensor(state.dq, np.float32, (B, J), finite=True)
            assert np.isfinite(from_tensor(state.q, np.float32, (B, J))).all()
            dq_max[step] = float(np.abs(dq).max())
            if phase == "dead":
                if any(e.kind == SafetyEventKind.WATCHDOG_STOP and e.header.step >= dead_since
                       for e in events) and dq_max[step] < REST_DQ:  # fmt: skip
                    rested_at = time.monotonic()
                continue
            if step >= 10 and nan_step is None:
                nan_step = step
            if step == 20:
                estop_steps["stop"] = step
                assert ask_estop(session, estop_key, "stop")["latched"] is True
            if step == 26:
                estop_steps["reset"] = step
                assert ask_estop(session, estop_key, "reset")["latched"] is False
                assert ask_estop(session, estop_key, "status")["latched"] is False
                replies = list(session.get(f"{estop_key}?halt", timeout=2.0))
                assert len(replies) == 1 and replies[0].err is not None
            if step >= 40:  # the policy dies: no more actions
                phase, dead_since, dead_at = "dead", step, time.monotonic()
                continue
            action = 0.5 * rng.standard_normal((B, 21)).astype(np.float32)
            if step == nan_step:
                action[1, 2] = np.nan
            message = PolicyAction(header=Header(step=step))
            to_tensor(action, message.action)
            actions.put(message)
    finally:
        session.close()

    # The arm moved while the policy acted, and rested soon after the watchdog fired.
    assert max(dq_max[k] for k in range(10, 40) if k in dq_max) > 5 * REST_DQ
    assert rested_at - dead_at < WATCHDOG_S + 3.0, f"rest after {rested_at - dead_at:.2f} s"
    kinds = [(e.kind, e.header.step) for e in events]
    rejected = [e for e in events if e.kind == SafetyEventKind.REJECTED_NONFINITE]
    assert [e.header.step for e in rejected] == [nan_step], kinds
    assert from_tensor(rejected[0].env_ids).tolist() == [1]
    latched = [s for k, s in kinds if k == SafetyEventKind.ESTOP_LATCHED]
    reset = [s for k, s in kinds if k == SafetyEventKind.ESTOP_RESET]
    assert len(latched) == 1 and len(reset) == 1, kinds
    # Latched: STOP although actions kept coming; after the reset the policy is followed.
    for step in range(estop_steps["stop"] + 1, estop_steps["reset"]):
        assert commands[step].mode == CommandMode.STOP, step
    assert commands[estop_steps["reset"] + 2].mode == CommandMode.TRACK
    assert all(commands[k].mode == CommandMode.TRACK for k in range(nan_step, 20))
    watchdog = [s for k, s in kinds if k == SafetyEventKind.WATCHDOG_STOP and s >= dead_since]
    assert watchdog == [dead_since], kinds
    assert any(len(e.stages) == 6 for e in events)  # per-stage statistics
