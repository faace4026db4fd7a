"""Shared fixtures: isolated Zenoh transports on loopback and `hamnet` subprocesses.

Every test that touches Zenoh gets its own namespace and its own rendezvous port, so tests
never see each other's traffic and never leave the machine.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import uuid
from collections.abc import Callable, Iterator

import pytest

from hamnet.runtime.transport import TransportConfig, free_port

LOG_TAIL_LINES = 30
"""Lines of each spawned process's output shown when its test failed."""


@pytest.fixture
def transport() -> TransportConfig:
    """A transport of its own: unique namespace, unique rendezvous endpoint."""
    return TransportConfig(
        namespace=f"test{uuid.uuid4().hex[:10]}", rendezvous=f"tcp/127.0.0.1:{free_port()}"
    )


def transport_args(transport: TransportConfig) -> list[str]:
    """Command-line flags that put a `hamnet` command on `transport`."""
    return ["--namespace", transport.namespace, "--rendezvous", transport.rendezvous]


STACK_FOLDERS = ("stack", "security")
"""Test folders whose tests start `hamnet` processes (services, routers, stacks)."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark `stack` every test that starts `hamnet` processes (those in `STACK_FOLDERS`, and
    any other that uses the `spawn` fixture) and `benchmark` those of tests/benchmarks, which
    run each benchmark's `--quick`: `bash scripts/test.sh --fast` leaves both out."""
    for item in items:
        folder = item.path.parent.name
        if folder in STACK_FOLDERS or "spawn" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.stack)
        if folder == "benchmarks":
            item.add_marker(pytest.mark.benchmark)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """Keep each phase's report on the test (`item.report_call`) for fixtures to read."""
    report = yield
    setattr(item, f"report_{report.when}", report)
    return report


@pytest.fixture
def spawn(request: pytest.FixtureRequest) -> Iterator[Callable[..., subprocess.Popen]]:
    """Start `python -m hamnet <args>` processes; all are stopped at teardown, and when the
    test failed, the last lines each one printed are shown with the failure."""
    processes: list[subprocess.Popen] = []

    def start(*args: str, netns: str | None = None) -> subprocess.Popen:
        """`hamnet <args>`, inside the network namespace `netns` when given (as root)."""
        inside = ["ip", "netns", "exec", netns] if netns else []
        process = subprocess.Popen(
            [*inside, sys.executable, "-m", "hamnet", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        processes.append(process)
        return process

    yield start
    for process in processes:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGTERM)
    for process in processes:
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    report = getattr(request.node, "report_call", None)
    if report is not None and report.failed:
        for process in processes:
            tail = process.stdout.read().splitlines()[-LOG_TAIL_LINES:]
            print(f"--- {' '.join(process.args)}:", *tail, sep="\n")
