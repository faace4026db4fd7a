"""`hamnet up` as a subprocess for the stack tests: its output collected line by line,
the pids of its children learned from its `started <process> (pid N)` log lines, and its
summary read back from `--summary-json`."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from hamnet.runtime.transport import TransportConfig
from tests.conftest import transport_args

STARTED = re.compile(r"started (\S+) \(pid (\d+)\)")


def alive(pid: int) -> bool:
    """Whether process `pid` exists and is not a zombie (read from /proc, no psutil)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def rss_mb(pid: int) -> float | None:
    """Resident memory of process `pid`, MB (VmRSS in /proc/<pid>/status); None once it is gone."""
    try:
        lines = Path(f"/proc/{pid}/status").read_text().splitlines()
    except FileNotFoundError:
        return None
    return next((int(line.split()[1]) / 1024 for line in lines if line.startswith("VmRSS:")), None)


class Up:
    """One `python -m hamnet up` run."""

    def __init__(
        self, stack: Path, transport: TransportConfig, *args: str, cwd: Path,
        wrapper: Sequence[str] = (),
    ) -> None:
        """`wrapper`: a command line that ends by running its arguments (e.g. `unshare ...
        sh -c '...; exec "$@"' sh`); the launcher's pid is then that command's."""
        self.summary_path = cwd / "summary.json"
        self.lines: list[str] = []
        self._changed = threading.Condition()
        self.process = subprocess.Popen(
            [*wrapper, sys.executable, "-m", "hamnet", "up", str(stack), *transport_args(transport),
             "--summary-json", str(self.summary_path), *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=cwd,
            start_new_session=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        threading.Thread(target=self._collect, daemon=True).start()

    def _collect(self) -> None:
        for line in self.process.stdout:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()

    @property
    def output(self) -> str:
        """Everything printed so far (children's prefixed lines and the launcher's logs)."""
        with self._changed:
            return "\n".join(self.lines)

    def wait_for(self, pattern: str, count: int = 1, timeout: float = 15.0) -> list[re.Match]:
        """The first `count` output lines matching `pattern`; fails after `timeout` seconds."""
        regex = re.compile(pattern)
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                matches = [m for m in map(regex.search, self.lines) if m]
                if len(matches) >= count:
                    return matches[:count]
                remaining = deadline - time.monotonic()
                assert remaining > 0, f"no {count} lines matching {pattern!r}:\n{self.output}"
                self._changed.wait(min(remaining, 0.2))

    def started(self) -> dict[str, list[int]]:
        """Pids of every start of every process, by label (`echo/a`), from the launcher's log."""
        pids: dict[str, list[int]] = {}
        for match in map(STARTED.search, self.output.splitlines()):
            if match:
                pids.setdefault(match[1], []).append(int(match[2]))
        return pids

    def wait(self, timeout: float = 20.0) -> int:
        """Exit status of the launcher; fails if it is still running after `timeout` seconds."""
        try:
            return self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"hamnet up still running after {timeout} s:\n{self.output}") from None

    def summary(self) -> dict:
        """The `--summary-json` document."""
        return json.loads(self.summary_path.read_text())

    def close(self) -> None:
        """Kill whatever is left: the launcher and every child it reported."""
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()
        for pids in self.started().values():
            for pid in pids:
                if alive(pid):
                    os.killpg(pid, signal.SIGKILL)


@contextmanager
def up(
    stack: Path, transport: TransportConfig, *args: str, cwd: Path, wrapper: Sequence[str] = ()
) -> Iterator[Up]:
    """Run `hamnet up stack` for the duration of the block; nothing outlives it."""
    run = Up(stack, transport, *args, cwd=cwd, wrapper=wrapper)
    try:
        yield run
    finally:
        run.close()
