"""The processes of a stack: start, restart after a crash, stop without leaving any behind.

Every worker of a service runs as `python -m hamnet <command> ...` in a session of its
own, so a Ctrl-C in the terminal reaches only the launcher, and the launcher can signal
the worker's whole process group (its own children included). A process that exits 0 has
finished and stays down; a non-zero exit or a signal is a crash, restarted after an
exponential back-off until its service's `max_restarts` is spent. Exit status
`EXIT_NO_RESTART` (74) says a restart would fail the same way (e.g. a full disk): that
process fails at once, without restarts. Stopping sends SIGTERM
to every group, waits up to a grace period, then sends SIGKILL to what is left.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum

from hamnet.launcher.output import Output
from hamnet.launcher.stack import ServiceSpec
from hamnet.runtime.service import EXIT_NO_RESTART, SUPERVISOR_PID_ENV

log = logging.getLogger(__name__)

HAMNET = (sys.executable, "-m", "hamnet")
"""How a process is started: `hamnet` in the launcher's own interpreter."""


class Outcome(str, Enum):
    """Where a process stands; the last one is its result in the summary."""

    PENDING = "pending"
    """Not started yet."""
    RUNNING = "running"
    RESTARTING = "restarting"
    """Crashed, waiting for its back-off before the next start."""
    FINISHED = "finished"
    """Exited 0 on its own."""
    FAILED = "failed"
    """Crashed with no restarts left."""
    STOPPED = "stopped"
    """Exited within the grace period after the launcher's SIGTERM."""
    KILLED = "killed"
    """Still running after the grace period: SIGKILL."""
    CRASHED = "crashed"
    """Crashed, and the stack stopped before its restart."""


@dataclass
class Process:
    """One worker of one service, across its restarts."""

    service: str
    """Service name in the stack file."""
    worker: str
    """Worker id."""
    spec: ServiceSpec
    """The service it belongs to (command, restart policy)."""
    argv: list[str]
    """Arguments after `hamnet` (the supervisor's program)."""
    outcome: Outcome = Outcome.PENDING
    pids: list[int] = field(default_factory=list)
    """Process id of every start, in order."""
    restarts: int = 0
    returncode: int | None = None
    """Exit status of the last run (negative: killed by that signal); None while running."""
    uptime_s: float = 0.0
    """Seconds spent running, over all runs."""
    started_at: float = 0.0
    """time.monotonic() of the latest start."""
    restart_at: float = 0.0
    """time.monotonic() at which a crashed process is started again."""
    ready_s: float | None = None
    """Seconds from the latest start to its liveliness token; None until it is seen."""
    popen: subprocess.Popen[bytes] | None = None

    @property
    def label(self) -> str:
        """`sim/0`: service and worker, as in the output prefix and the summary."""
        return f"{self.service}/{self.worker}"

    @property
    def exit_text(self) -> str:
        """`exit 1`, `killed by SIGKILL`, or `running`."""
        return describe_exit(self.returncode)


def describe_exit(returncode: int | None) -> str:
    """How a process ended, from its Popen return code."""
    if returncode is None:
        return "running"
    if returncode < 0:
        return f"killed by {signal.Signals(-returncode).name}"
    return f"exit {returncode}"


class Supervisor:
    """Starts, restarts and stops the processes of a stack."""

    def __init__(
        self, processes: Sequence[Process], output: Output, program: Sequence[str] = HAMNET
    ) -> None:
        self.processes = list(processes)
        self._output = output
        self._program = list(program)
        self._env: Mapping[str, str] = {
            **os.environ,
            "PYTHONUNBUFFERED": "1",
            SUPERVISOR_PID_ENV: str(os.getpid()),
        }
        self._followers: list[threading.Thread] = []

    def start(self, process: Process) -> None:
        """Start (or restart) `process` now."""
        popen = subprocess.Popen(
            [*self._program, *process.argv],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            env=self._env,
        )
        process.popen, process.outcome, process.returncode = popen, Outcome.RUNNING, None
        process.started_at, process.ready_s = time.monotonic(), None
        process.pids.append(popen.pid)
        self._followers.append(self._output.follow(process.label, popen.stdout))
        log.info("started %s (pid %d): hamnet %s", process.label, popen.pid, " ".join(process.argv))

    def step(self) -> list[Process]:
        """Start pending processes, notice exits and start due restarts.

        Returns:
            The processes that exited since the last call.
        """
        exited = []
        for process in self.processes:
            if process.outcome is Outcome.RUNNING and process.popen.poll() is not None:
                self._reap(process)
                self._after_exit(process)
                exited.append(process)
            elif process.outcome is Outcome.PENDING:
                self.start(process)
            elif process.outcome is Outcome.RESTARTING and time.monotonic() >= process.restart_at:
                process.restarts += 1
                self.start(process)
        return exited

    def _after_exit(self, process: Process) -> None:
        policy = process.spec.restart
        if process.returncode == 0:
            process.outcome = Outcome.FINISHED
            log.info("%s finished (exit 0)", process.label)
        elif process.returncode == EXIT_NO_RESTART:
            process.outcome = Outcome.FAILED
            log.error("%s stopped on a fault a restart cannot fix (exit %d): not restarted",
                      process.label, EXIT_NO_RESTART)
        elif process.restarts < policy.max_restarts:
            delay = policy.delay_s(process.restarts)
            process.outcome, process.restart_at = Outcome.RESTARTING, time.monotonic() + delay
            log.warning(
                "%s crashed (%s); restart %d of %d in %.3g s", process.label,
                process.exit_text, process.restarts + 1, policy.max_restarts, delay,
            )
        else:
            process.outcome = Outcome.FAILED
            log.error(
                "%s crashed (%s) with no restarts left (max_restarts: %d)",
                process.label, process.exit_text, policy.max_restarts,
            )

    def _reap(self, process: Process) -> None:
        """Record the exit of `process` and kill anything left in its process group."""
        process.returncode = process.popen.wait()
        process.uptime_s += time.monotonic() - process.started_at
        _signal_group(process.popen.pid, signal.SIGKILL)

    def stop(self, grace_s: float, spare: Collection[str] = ()) -> None:
        """Stop every process: SIGTERM to each group, then SIGKILL after `grace_s` seconds.

        Processes of the services in `spare` keep running (a stack's router, which carries
        the others' last reports); a later call stops them.
        """
        running = [p for p in self.processes if p.outcome is Outcome.RUNNING and p.service not in spare]
        for process in self.processes:
            if process.outcome is Outcome.RESTARTING:
                process.outcome = Outcome.CRASHED
        for process in running:
            _signal_group(process.popen.pid, signal.SIGTERM)
        deadline = time.monotonic() + grace_s
        while time.monotonic() < deadline and any(p.popen.poll() is None for p in running):
            time.sleep(0.02)
        for process in running:
            if process.popen.poll() is None:
                log.warning("%s still running %g s after SIGTERM: SIGKILL", process.label, grace_s)
                _signal_group(process.popen.pid, signal.SIGKILL)
                process.outcome = Outcome.KILLED
            else:
                process.outcome = Outcome.STOPPED
            self._reap(process)
        for follower in self._followers if not spare else ():
            follower.join(timeout=1.0)


def _signal_group(pgid: int, signum: signal.Signals) -> None:
    """Send `signum` to a process group; a group that is already gone is fine."""
    try:
        os.killpg(pgid, signum)
    except ProcessLookupError:
        pass
