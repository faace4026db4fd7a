"""The end-of-run report of `hamnet up`: how the stack ended and whether it ran with TLS
and access control, and for every process its restarts, uptime, exit status and what its
Health reports said; the services not built yet; the declared output files that exist.
Printed as a table, optionally saved as JSON.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from hamnet.launcher.secure import Security
from hamnet.launcher.supervisor import Process
from hamnet.launcher.watch import HealthBoard, Liveliness
from hamnet.runtime.events import success_line
from hamnet.runtime.numbered_files import recording_files


@dataclass(frozen=True)
class ProcessReport:
    """How one worker of one service ran."""

    service: str
    worker: str
    command: str
    critical: bool
    """Whether its failure stops the stack (false: an auxiliary service)."""
    outcome: str
    """finished, stopped, killed, failed, crashed or pending (see supervisor.Outcome)."""
    exit: str
    """`exit 0`, `killed by SIGKILL`, ..."""
    returncode: int | None
    restarts: int
    uptime_s: float
    ready_s: float | None
    """Seconds from its latest start to its liveliness token; None if not seen."""
    announced: int
    """Liveliness tokens seen (one per run that got ready)."""
    pids: list[int]
    received: dict[str, int]
    """Payloads received per subscription, from its Health reports."""
    published: dict[str, int]
    """Messages published per key, from its Health reports."""
    drops: dict[str, int]
    """Dropped payloads per `key: reason`."""
    events: dict[str, int]
    """Notable events by name from its Health reports (the sim's `loop_stalls`: times the
    closed loop sent no command for `--stall-s`)."""
    loop_rate_hz: float | None
    """Mean loop rate while running."""


@dataclass(frozen=True)
class Report:
    """The whole run."""

    stack: str
    namespace: str
    ended: str
    """Why the stack ended, in words."""
    exit_code: int
    elapsed_s: float
    processes: list[ProcessReport]
    not_built: str
    """`sim (issue #3), ...`: services that could not run because they are not built yet."""
    outputs: dict[str, int]
    """Files the run wrote for the declared outputs (every part of a sequence), with their
    sizes in bytes."""
    outputs_missing: list[str]
    """Declared outputs the run wrote nothing for."""
    security: Security = field(default_factory=Security)
    """Whether links were mutual TLS, and whose access rules held."""

    @property
    def auxiliary_failed(self) -> list[str]:
        """`record/0 (exit 74)`: every failed process of an auxiliary service."""
        return [
            f"{p.service}/{p.worker} ({p.exit})"
            for p in self.processes
            if p.outcome == "failed" and not p.critical
        ]

    def to_json(self) -> str:
        """The report as a JSON document."""
        return json.dumps(dataclasses.asdict(self), indent=2)


def process_report(process: Process, liveliness: Liveliness, health: HealthBoard) -> ProcessReport:
    """Report of one process, from the supervisor's record and what the network said."""
    command = process.spec.command
    totals = health.totals(command, process.worker)
    return ProcessReport(
        service=process.service,
        worker=process.worker,
        command=command,
        critical=process.spec.is_critical,
        outcome=process.outcome.value,
        exit=process.exit_text,
        returncode=process.returncode,
        restarts=process.restarts,
        uptime_s=round(process.uptime_s, 3),
        ready_s=process.ready_s,
        announced=liveliness.announcements(command, process.worker),
        pids=list(process.pids),
        received=dict(totals.received),
        published=dict(totals.published),
        drops={f"{key}: {reason}": n for (key, reason), n in sorted(totals.drops.items())},
        events=dict(sorted(totals.events.items())),
        loop_rate_hz=None if totals.loop_rate_hz is None else round(totals.loop_rate_hz, 2),
    )


def output_state(paths: tuple[Path, ...]) -> dict[str, tuple[int, int]]:
    """(mtime in ns, size) of every file of the declared outputs' sequences (a file output
    stands for all of it, `hamnet.runtime.numbered_files`: `stack.mcap`, `stack.1.mcap`,
    rotated files): taken before a run, it tells which files the run wrote."""
    files = recording_files([path for path in paths if not path.is_dir()])
    return {str(f): (f.stat().st_mtime_ns, f.stat().st_size) for f in files if f.is_file()}


def output_files(
    paths: tuple[Path, ...], before: dict[str, tuple[int, int]]
) -> tuple[dict[str, int], list[str]]:
    """(the files the run wrote for the declared outputs, with their sizes in bytes; the
    outputs it wrote nothing for). `before`: `output_state` at the run's start; a file new
    since, or changed, is the run's. A folder's size is that of every file under it."""
    existing: dict[str, int] = {}
    missing: list[str] = []
    for path in paths:
        if path.is_dir():
            existing[str(path)] = sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
            continue
        written = {
            name: size
            for name, (mtime, size) in output_state((path,)).items()
            if before.get(name) != (mtime, size)
        }
        existing.update(written)
        if not written:
            missing.append(str(path))
    return existing, missing


def render(report: Report) -> str:
    """The report as a readable table."""
    lines = [
        (
            f"stack {report.stack} (namespace {report.namespace}): {report.ended} "
            f"after {report.elapsed_s:.1f} s; exit status {report.exit_code}"
        ),
        report.security.text(),
    ]
    rows = [
        (
            "PROCESS",
            "COMMAND",
            "OUTCOME",
            "EXIT",
            "RESTARTS",
            "UPTIME",
            "READY",
            "RECEIVED",
            "PUBLISHED",
            "DROPS",
            "LOOP",
        )
    ]
    for p in report.processes:
        rows.append(
            (
                f"{p.service}/{p.worker}",
                p.command,
                p.outcome,
                p.exit,
                str(p.restarts),
                f"{p.uptime_s:.1f} s",
                "-" if p.ready_s is None else f"{p.ready_s:.1f} s",
                str(sum(p.received.values())),
                str(sum(p.published.values())),
                str(sum(p.drops.values())),
                "-" if p.loop_rate_hz is None else f"{p.loop_rate_hz:.1f} Hz",
            )
        )
    if report.processes:
        widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
        lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
    for p in report.processes:
        lines += [f"  {p.service}/{p.worker} dropped {n} on {kind}" for kind, n in p.drops.items()]
        lines += [
            f"  {p.service}/{p.worker}: {n} {name.replace('_', ' ')}"
            for name, n in p.events.items()
        ]
    for p in report.processes:
        success = success_line(p.events)
        if success is not None:
            lines.append(f"{p.service}/{p.worker}: {success}")
    if report.auxiliary_failed:
        lines.append(
            f"auxiliary, failed while the stack went on: {', '.join(report.auxiliary_failed)}"
        )
    if report.not_built:
        lines.append(f"not built yet: {report.not_built}")
    for path, size in report.outputs.items():
        lines.append(f"written: {path} ({_size(size)})")
    for path in report.outputs_missing:
        lines.append(f"not written: {path}")
    return "\n".join(lines)


def _size(n: int) -> str:
    power = min(int(math.log(max(n, 1), 1024)), 3)
    return f"{n} B" if power == 0 else f"{n / 1024**power:.1f} {('KiB', 'MiB', 'GiB')[power - 1]}"
