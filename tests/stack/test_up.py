"""`hamnet up` over real Zenoh on loopback: small stacks of `hamnet echo` processes are
started, announce themselves, get restarted after SIGKILL, exhaust their restarts when they
keep crashing, and all stop on SIGTERM without leaving a process behind.

Each test runs its own namespace on its own rendezvous port (the `transport` fixture), and
learns the children's pids from the launcher's `started <process> (pid N)` lines.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from hamnet.runtime import keys
from hamnet.runtime.transport import TransportConfig, open_session
from tests.stack.up import alive, up


class Tokens:
    """Liveliness events of one namespace seen from a session of the test's own."""

    def __init__(self, transport: TransportConfig) -> None:
        self.events: list[tuple[str, str]] = []
        self._lock = threading.Lock()
        self._session = open_session(transport)
        self._subscriber = self._session.liveliness().declare_subscriber(
            f"{keys.ROOT}/{transport.namespace}/alive/**", self._on_sample, history=True
        )

    def _on_sample(self, sample: zenoh.Sample) -> None:
        _, service, worker = keys.parse_alive_key(str(sample.key_expr))
        with self._lock:
            self.events.append((f"{service}/{worker}", "PUT" if sample.kind == zenoh.SampleKind.PUT else "DELETE"))

    def of(self, source: str) -> list[str]:
        """PUT/DELETE events of one `service/worker`, in order."""
        with self._lock:
            return [kind for name, kind in self.events if name == source]

    def wait(self, source: str, expected: list[str], timeout: float = 10.0) -> None:
        deadline = time.monotonic() + timeout
        while self.of(source) != expected:
            assert time.monotonic() < deadline, f"{source}: {self.of(source)} != {expected}"
            time.sleep(0.05)

    def close(self) -> None:
        self._subscriber.undeclare()
        self._session.close()


@pytest.fixture
def tokens(transport: TransportConfig) -> Iterator[Tokens]:
    watcher = Tokens(transport)
    yield watcher
    watcher.close()


def write_stack(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "stack.yaml"
    path.write_text(text)
    return path


def assert_all_gone(pids: list[int]) -> None:
    assert pids
    left = [pid for pid in pids if alive(pid)]
    assert not left, f"processes left behind: {left}"


def by_label(summary: dict) -> dict[str, dict]:
    return {f"{p['service']}/{p['worker']}": p for p in summary["processes"]}


def test_every_process_announces_itself_and_sigterm_stops_them_all(tmp_path, transport, tokens):
    stack = write_stack(tmp_path, """
services:
  watch: {command: echo, args: {period-s: 1}}
  echo: {workers: [a, b]}
""")
    with up(stack, transport, cwd=tmp_path) as run:
        run.wait_for("stack ready: every process announced itself")
        for source in ("echo/0", "echo/a", "echo/b", "up/0"):
            tokens.wait(source, ["PUT"])
        started = run.started()
        assert sorted(started) == ["echo/a", "echo/b", "watch/0"]
        # The children talk to each other. By the second rate line watch has sent a RUNNING
        # health report: the first line and the first report fall due together.
        run.wait_for(r"watch/0 \| .* hamnet/.*/health/echo/a", count=2)
        run.process.send_signal(signal.SIGTERM)
        assert run.wait() == 0, run.output
    summary = run.summary()
    assert summary["ended"] == "stopped by a signal" and summary["exit_code"] == 0
    processes = by_label(summary)
    for label, pids in started.items():
        assert processes[label]["pids"] == pids
        assert processes[label]["outcome"] == "stopped"
        assert processes[label]["announced"] == 1
        assert processes[label]["ready_s"] is not None
    assert processes["watch/0"]["received"]["stack"] > 0  # from its Health reports
    assert processes["watch/0"]["loop_rate_hz"] > 0
    assert_all_gone([pid for pids in started.values() for pid in pids])


def test_process_killed_by_sigkill_restarts_and_announces_itself_again(tmp_path, transport, tokens):
    stack = write_stack(tmp_path, """
services:
  echo: {workers: [a, b], restart: {max_restarts: 2, backoff_s: 0.1}}
""")
    with up(stack, transport, cwd=tmp_path) as run:
        run.wait_for("stack ready")
        tokens.wait("echo/a", ["PUT"])
        [first] = run.started()["echo/a"]
        os.kill(first, signal.SIGKILL)
        run.wait_for(r"echo/a crashed \(killed by SIGKILL\); restart 1 of 2 in 0.1 s")
        run.wait_for(r"echo/a ready after", count=2)
        tokens.wait("echo/a", ["PUT", "DELETE", "PUT"])
        [_, second] = run.started()["echo/a"]
        assert second != first and alive(second) and not alive(first)
        run.process.send_signal(signal.SIGINT)
        assert run.wait() == 0, run.output
    processes = by_label(run.summary())
    assert processes["echo/a"]["restarts"] == 1
    assert processes["echo/a"]["announced"] == 2
    assert processes["echo/a"]["pids"] == [first, second]
    assert processes["echo/b"]["restarts"] == 0
    assert_all_gone([first, second, *processes["echo/b"]["pids"]])


def test_process_that_keeps_crashing_exhausts_its_restarts_and_fails_the_stack(tmp_path, transport):
    bad_config = tmp_path / "bad.json5"
    bad_config.write_text("{ not json5")  # passes `--check` (the file exists), fails at start
    stack = write_stack(tmp_path, f"""
services:
  broken:
    command: echo
    args: {{zenoh-config: {bad_config}}}
    restart: {{max_restarts: 2, backoff_s: 0.05, backoff_max_s: 0.1}}
  watch: {{command: echo, workers: [w]}}
""")
    with up(stack, transport, cwd=tmp_path) as run:
        assert run.wait(timeout=30) == 1, run.output
    assert "broken/0 crashed (exit 2) with no restarts left (max_restarts: 2)" in run.output
    summary = run.summary()
    assert summary["exit_code"] == 1
    assert summary["ended"] == "broken/0 crashed with no restarts left"
    processes = by_label(summary)
    assert processes["broken/0"]["outcome"] == "failed"
    assert processes["broken/0"]["restarts"] == 2 and len(processes["broken/0"]["pids"]) == 3
    assert processes["watch/w"]["outcome"] == "stopped"
    assert_all_gone([pid for p in processes.values() for pid in p["pids"]])


def test_stack_ends_when_its_until_service_finishes(tmp_path, transport):
    stack = write_stack(tmp_path, """
until: once
services:
  once: {command: echo, args: {duration-s: 1}}
  watch: {command: echo, workers: [w]}
""")
    with up(stack, transport, cwd=tmp_path) as run:
        assert run.wait() == 0, run.output
    summary = run.summary()
    assert summary["ended"] == "once finished"
    processes = by_label(summary)
    assert processes["once/0"]["outcome"] == "finished"
    assert processes["once/0"]["restarts"] == 0  # exit 0 is not a crash
    assert processes["watch/w"]["outcome"] == "stopped"
    assert_all_gone([pid for p in processes.values() for pid in p["pids"]])


def test_children_stop_when_the_launcher_is_killed(tmp_path, transport):
    """SIGKILL gives the launcher no chance to stop its children; they notice they were
    re-parented and stop themselves instead of running on unsupervised."""
    stack = write_stack(tmp_path, "services:\n  echo: {workers: [a, b]}\n")
    with up(stack, transport, cwd=tmp_path) as run:
        run.wait_for("stack ready")
        pids = [pid for started in run.started().values() for pid in started]
        os.kill(run.process.pid, signal.SIGKILL)
        deadline = time.monotonic() + 10
        while any(alive(pid) for pid in pids) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert_all_gone(pids)


def test_a_hung_process_is_reported_when_its_liveliness_token_expires(tmp_path, transport):
    """A process that stops answering keeps running, so only Zenoh liveliness can tell:
    with a 1 s lease its token is withdrawn, no STOPPING report came, and once the grace
    (`TOKEN_GONE_GRACE_S`) has passed the launcher says so."""
    zenoh_file = tmp_path / "zenoh.json5"
    zenoh_file.write_text("{ transport: { link: { tx: { lease: 1000 } } } }")
    stack = write_stack(tmp_path, "services:\n  echo: {workers: [a]}\n")
    with up(stack, transport, "--zenoh-config", str(zenoh_file), cwd=tmp_path) as run:
        run.wait_for("stack ready")
        [pid] = run.started()["echo/a"]
        os.kill(pid, signal.SIGSTOP)
        try:
            run.wait_for("echo/a lost its liveliness token while running", timeout=25)
        finally:
            os.kill(pid, signal.SIGCONT)
        run.process.send_signal(signal.SIGTERM)
        assert run.wait() == 0, run.output
