"""The supervisor with plain Python scripts in place of `hamnet` commands: crashes are
restarted up to the limit, exit 0 is final, and stopping leaves nothing behind, not even a
process that ignores SIGTERM or the children a process started in its group."""

from __future__ import annotations

import io
import re
import sys
import time

from hamnet.launcher.output import Output
from hamnet.launcher.stack import RestartPolicy, ServiceSpec
from hamnet.launcher.supervisor import Outcome, Process, Supervisor
from tests.stack.up import alive

STUBBORN = """
import signal, subprocess, sys, time
signal.signal(signal.SIGTERM, signal.SIG_IGN)
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
print("child", child.pid, flush=True)
time.sleep(60)
"""
"""Ignores SIGTERM and starts a child in its process group."""

LEAVES_A_CHILD = """
import subprocess, sys
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
print("child", child.pid, flush=True)
"""
"""Exits 0 at once, leaving a child behind in its process group."""


def supervise(script: str, restart: RestartPolicy | None = None) -> tuple[Supervisor, io.StringIO]:
    spec = ServiceSpec("script", restart=restart or RestartPolicy())
    process = Process("script", "0", spec, ["-c", script])
    stream = io.StringIO()
    return Supervisor([process], Output(stream, [process.label], colour=False), [sys.executable]), stream


def step_until(supervisor: Supervisor, outcome: Outcome, timeout: float = 10.0) -> Process:
    [process] = supervisor.processes
    deadline = time.monotonic() + timeout
    while process.outcome is not outcome:
        assert time.monotonic() < deadline, f"still {process.outcome} after {timeout} s"
        supervisor.step()
        time.sleep(0.01)
    return process


def child_pid(stream: io.StringIO, timeout: float = 10.0) -> int:
    deadline = time.monotonic() + timeout
    while not (match := re.search(r"script/0 \| child (\d+)", stream.getvalue())):
        assert time.monotonic() < deadline, stream.getvalue()
        time.sleep(0.01)
    return int(match[1])


def test_crashing_process_is_restarted_until_its_limit_then_fails() -> None:
    supervisor, stream = supervise("import sys; print('boom'); sys.exit(3)",
                                   RestartPolicy(max_restarts=2, backoff_s=0.05, backoff_max_s=0.1))
    started = time.monotonic()
    process = step_until(supervisor, Outcome.FAILED)
    assert (process.restarts, len(process.pids), process.returncode) == (2, 3, 3)
    assert time.monotonic() - started >= 0.05 + 0.1  # the back-off doubled, up to its bound
    supervisor.stop(grace_s=1.0)
    assert stream.getvalue().count("script/0 | boom") == 3


def test_exit_0_finishes_without_restart_and_kills_what_it_left_in_its_group() -> None:
    supervisor, stream = supervise(LEAVES_A_CHILD)
    process = step_until(supervisor, Outcome.FINISHED)
    assert (process.restarts, process.returncode) == (0, 0)
    orphan = child_pid(stream)
    deadline = time.monotonic() + 5
    while alive(orphan):
        assert time.monotonic() < deadline, "the child of a finished process survived"
        time.sleep(0.01)


def test_stop_kills_a_process_that_ignores_sigterm_and_its_children() -> None:
    supervisor, stream = supervise(STUBBORN)
    process = step_until(supervisor, Outcome.RUNNING)
    grandchild = child_pid(stream)
    started = time.monotonic()
    supervisor.stop(grace_s=0.3)
    assert time.monotonic() - started >= 0.3
    assert process.outcome is Outcome.KILLED
    assert process.exit_text == "killed by SIGKILL"
    deadline = time.monotonic() + 5
    while alive(process.pids[0]) or alive(grandchild):
        assert time.monotonic() < deadline, "a process survived stop()"
        time.sleep(0.01)
