"""The secure stack end to end under `hamnet up`.

compose/secure/stack.yaml, made small (the control loop: sim, perception, policy on random
weights, safety) and put on a free port: `hamnet certs stack` makes its certificates,
`hamnet up` starts its router (mutual TLS, the access rules) and every service as a client
under its own certificate. Once the loop turned, the stack is stopped and its summary
read. Every wait is on a condition, with generous deadlines."""

from __future__ import annotations

import os
import signal
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import yaml

from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.codec import decode
from hamnet.runtime.transport import TransportConfig, free_port
from hamnet.security.certs import issue
from hamnet.security.certs_cli import main as certs
from tests.security.clients import Clients
from tests.stack.up import Up, up

SECURE = Path(__file__).resolve().parents[2] / "compose" / "secure"
DEADLINE_S = 60.0
"""Generous bound for anything to happen (the machine is shared with training runs)."""

NUM_ENVS = 2
SERVICES = {
    "sim": {"args": {"num-envs": NUM_ENVS, "report-period-s": 5}},
    "perception": {"args": {"report-period-s": 5}},
    "policy": {"args": {"random-init": "hamnet"}},
    "safety": {},
}
"""The control loop of compose/secure/stack.yaml (its trainer, rollout worker and monitor
are left out: the test plays the trainer)."""


class Running(Clients):
    """The secure stack under `hamnet up`, and clients of its router."""

    def __init__(self, run: Up, certs: Path, namespace: str, endpoint: str) -> None:
        super().__init__(certs, namespace, endpoint)
        self.run = run

    def collect(self, path: str, kind: type, identity: str = "observer") -> list:
        """Every message published on topic `path` from now on, decoded, as it arrives."""
        received: list = []
        session = self.client(identity)
        session.declare_subscriber(self.key(path),
                                   lambda s: received.append(decode(kind, s.payload.to_bytes())))  # fmt: skip
        return received

    def wait(self, condition: Callable[[], bool], what: str) -> None:
        """Wait until `condition()` holds, while the stack runs."""
        deadline = time.monotonic() + DEADLINE_S
        while not condition():
            assert self.run.process.poll() is None, f"hamnet up ended:\n{self.run.output[-3000:]}"
            assert time.monotonic() < deadline, f"never: {what}\n{self.run.output[-3000:]}"
            time.sleep(0.1)


@pytest.fixture(scope="module")
def stack(tmp_path_factory) -> Iterator[Running]:
    folder = tmp_path_factory.mktemp("secure-up")
    endpoint = f"tls/127.0.0.1:{free_port()}"
    document = yaml.safe_load((SECURE / "stack.yaml").read_text())
    document["secure"].update(tls_dir=str(folder / "certs"), access=str(SECURE / "router.json5"),
                              listen=endpoint)  # fmt: skip
    document.update(services=SERVICES, duration_s=300)  # a bound; the last test stops it
    path = folder / "stack.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    assert certs(["stack", str(path)]) == 0
    for name in ("intruder", "observer", "trainer"):  # the test plays the trainer
        issue(folder / "certs", name, days=1)
    namespace = f"secure{uuid.uuid4().hex[:8]}"
    with up(path, TransportConfig(namespace=namespace), cwd=folder) as run:
        running = Running(run, folder / "certs", namespace, endpoint)
        try:
            yield running
        finally:
            running.close()


def test_the_secure_stack_closes_the_loop_and_says_it_is_secure(stack: Running) -> None:
    """Every service joined the router over TLS with its own certificate, the loop turned
    (the sim stepped on safety's commands), and the summary names TLS and the rules."""
    states = stack.collect("sim/<w>/state", RobotState)
    stack.wait(lambda: len({s.header.step for s in states}) >= 50, "50 sim steps")
    os.killpg(stack.run.process.pid, signal.SIGTERM)
    assert stack.run.wait(timeout=60) == 0, stack.run.output[-3000:]
    summary = stack.run.summary()
    assert summary["security"] == {"tls_dir": str(stack.certs),
                                   "access": str(SECURE / "router.json5"),
                                   "router": stack.endpoint}  # fmt: skip
    processes = {p["service"]: p for p in summary["processes"]}
    assert list(processes) == ["router", *SERVICES]
    assert all(p["announced"] >= 1 and p["restarts"] == 0 for p in processes.values()), processes
    sim = processes["sim"]
    steps = sim["published"][stack.key("sim/<w>/transition")]
    assert steps >= 50 and sim["received"]["command"] >= steps, sim
    assert processes["safety"]["published"][stack.key("safety/<w>/command")] >= steps
    assert "secure: mutual TLS" in stack.run.output
