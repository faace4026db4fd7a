"""The service docs/runtime.md walks through (`examples/hold_policy.py`) is the file the
document shows, under 60 lines, and it closes the loop: with `hamnet sim` and `hamnet safety`
as processes on real Zenoh, the lock-step sim advances only on its answers."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox
from hamnet.runtime.transport import TransportConfig, open_session
from tests.conftest import transport_args

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples/hold_policy.py"


def test_the_document_shows_the_example_whole_and_it_is_under_60_lines() -> None:
    text = EXAMPLE.read_text()
    assert f"```python\n{text}```" in (ROOT / "docs/runtime.md").read_text()
    assert len(text.splitlines()) < 60


def test_the_example_closes_the_loop_with_the_sim_and_safety(
    spawn, transport: TransportConfig
) -> None:
    net = transport_args(transport)
    processes = [spawn("sim", "--num-envs", "2", "--num-objects", "2", "--nthread", "1", *net),
                 spawn("safety", *net)]  # fmt: skip
    example = subprocess.Popen(
        [sys.executable, str(EXAMPLE), *net], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("state", contract.topic("sim/<w>/state").key(transport.namespace, w="0"),
                    RobotState)  # fmt: skip
    step, deadline = 0, time.monotonic() + 90
    try:
        while step < 20:
            for process in (*processes, example):
                assert process.poll() is None, process.stdout.read()
            assert time.monotonic() < deadline, f"the sim reached step {step}"
            received = inbox.get(timeout=0.5)
            step = max(step, received.value.header.step) if received else step
    finally:
        session.close()
        example.terminate()
        output = example.communicate(timeout=30)[0]
    assert example.returncode == 0, output
