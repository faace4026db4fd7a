"""Service lifecycle over real Zenoh: liveliness token while running, health reports with
drop counts, and a graceful stop on SIGTERM."""

from __future__ import annotations

import signal
import time

from hamnet.proto.health_pb2 import Health, ServiceState
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.codec import decode
from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.runtime.transport import open_session
from tests.conftest import transport_args

ALIVE = contract.topic("alive/<service>/<w>")
HEALTH = contract.topic("health/<service>/<w>")


def test_token_and_health_follow_the_service_lifecycle(transport) -> None:
    observer = open_session(transport)
    alive_key = ALIVE.key(transport.namespace, service="probe", w="3")
    reports: list[Health] = []
    observer.declare_subscriber(
        HEALTH.key(transport.namespace, service="probe", w="3"),
        lambda sample: reports.append(decode(Health, sample.payload.to_bytes())),
    )
    state_key = contract.topic("sim/<w>/state").key(transport.namespace, w="0")
    with Service(ServiceIdentity("probe", "3"), transport, health_period_s=0.2) as service:
        service.inbox.subscribe("state", state_key, RobotState)
        deadline = time.monotonic() + 10
        while not list(observer.liveliness().get(alive_key, timeout=1.0)):
            assert time.monotonic() < deadline
        while service.inbox.received["state"] == 0 and time.monotonic() < deadline:
            observer.put(state_key, b"\xff not a message")
            service.receive(timeout=0.05)
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            service.receive(timeout=0.05)
    time.sleep(0.3)
    assert not list(observer.liveliness().get(alive_key, timeout=1.0))
    states = [report.state for report in reports]
    assert states[0] == ServiceState.STARTING and states[-1] == ServiceState.STOPPING
    assert ServiceState.RUNNING in states
    last = reports[-1]
    assert last.service == "probe" and last.worker == "3" and last.uptime_s > 0.5
    assert [(d.key, d.reason) for d in last.drops] == [(state_key, "decode")]
    assert last.drops[0].count == last.received["state"] >= 1
    observer.close()


def test_sigterm_stops_a_service_cleanly(spawn, transport) -> None:
    process = spawn("echo", "--worker", "s1", *transport_args(transport))
    observer = open_session(transport)
    alive_key = ALIVE.key(transport.namespace, service="echo", w="s1")
    deadline = time.monotonic() + 20
    while not list(observer.liveliness().get(alive_key, timeout=1.0)):
        assert time.monotonic() < deadline and process.poll() is None
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=10) == 0
    assert "received SIGTERM, stopping" in process.stdout.read()
    assert not list(observer.liveliness().get(alive_key, timeout=1.0))
    observer.close()
