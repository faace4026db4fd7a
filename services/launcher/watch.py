"""What the launcher learns from the network about the processes it runs.

`Liveliness` follows the liveliness tokens of one namespace (`hamnet/<ns>/alive/<service>/<w>`,
held by every service once it is ready), so the launcher can tell when each process has
announced itself, and again after each restart. `HealthBoard` keeps the Health reports
(`hamnet/<ns>/health/<service>/<w>`) of each process, summed over its restarts, for the
summary: messages received and published, drops by reason, events (e.g. the sim's
`loop_stalls`), loop rate.
"""

from __future__ import annotations

import threading
import time
from collections import Counter
from dataclasses import dataclass, field

import zenoh

from hamnet.proto.health_pb2 import Health, ServiceState
from hamnet.runtime import contract, keys

ALIVE = contract.topic("alive/<service>/<w>")
HEALTH = contract.topic("health/<service>/<w>")


class Liveliness:
    """Liveliness tokens of one namespace, as a subscriber with history sees them."""

    def __init__(self, session: zenoh.Session, namespace: str) -> None:
        self._lock = threading.Lock()
        self._announced: dict[tuple[str, str], list[float]] = {}
        self._withdrawn: dict[tuple[str, str], list[float]] = {}
        self._subscriber = session.liveliness().declare_subscriber(
            ALIVE.pattern_in(namespace), self._on_sample, history=True
        )

    def _on_sample(self, sample: zenoh.Sample) -> None:
        _, service, worker = keys.parse_alive_key(str(sample.key_expr))
        seen = self._announced if sample.kind == zenoh.SampleKind.PUT else self._withdrawn
        with self._lock:
            seen.setdefault((service, worker), []).append(time.monotonic())

    def announced_since(self, service: str, worker: str, since: float) -> float | None:
        """time.monotonic() of the first token of `service/worker` seen at or after `since`."""
        return self._first_since(self._announced, service, worker, since)

    def withdrawn_at(self, service: str, worker: str, since: float) -> float | None:
        """time.monotonic() of the first withdrawal of `service/worker`'s token seen at or
        after `since`, or None.

        Zenoh withdraws a token when its session closes or loses every link
        (`hamnet.launcher.tokens` says what that means for a running process).
        """
        return self._first_since(self._withdrawn, service, worker, since)

    def _first_since(
        self, seen: dict[tuple[str, str], list[float]], service: str, worker: str, since: float
    ) -> float | None:
        with self._lock:
            return next((t for t in seen.get((service, worker), []) if t >= since), None)

    def announcements(self, service: str, worker: str) -> int:
        """How many times `service/worker` declared its token."""
        with self._lock:
            return len(self._announced.get((service, worker), []))

    def close(self) -> None:
        """Stop following tokens."""
        self._subscriber.undeclare()


@dataclass
class HealthTotals:
    """Health reports of one process, summed over its restarts."""

    received: Counter[str] = field(default_factory=Counter)
    """Payloads received per subscription, over finished runs."""
    published: Counter[str] = field(default_factory=Counter)
    """Messages published per key, over finished runs."""
    drops: Counter[tuple[str, str]] = field(default_factory=Counter)
    """Dropped payloads per (key, reason), over finished runs."""
    events: Counter[str] = field(default_factory=Counter)
    """Notable events by name (`Health.events`), over finished runs."""
    loop_rates_hz: list[float] = field(default_factory=list)
    """Loop rate of every report sent while running."""
    last: Health | None = None
    """Latest report of the current run; its counters are not in the totals yet."""

    def add(self, report: Health) -> None:
        """Take one report; a smaller uptime than the last one means the process restarted."""
        if self.last is not None and report.uptime_s < self.last.uptime_s:
            self._fold(self.last)
        self.last = report
        if report.state == ServiceState.RUNNING:
            self.loop_rates_hz.append(report.loop_rate_hz)

    def _fold(self, report: Health) -> None:
        self.received.update(dict(report.received))
        self.published.update(dict(report.published))
        self.drops.update({(d.key, d.reason): d.count for d in report.drops})
        self.events.update(dict(report.events))

    def totals(self) -> HealthTotals:
        """The counters of every run, the current one included."""
        total = HealthTotals(
            Counter(self.received),
            Counter(self.published),
            Counter(self.drops),
            Counter(self.events),
        )
        if self.last is not None:
            total._fold(self.last)
        total.loop_rates_hz = list(self.loop_rates_hz)
        return total

    @property
    def loop_rate_hz(self) -> float | None:
        """Mean loop rate while running, or None before the first report."""
        rates = self.loop_rates_hz
        return sum(rates) / len(rates) if rates else None


class HealthBoard:
    """The health of every process of a namespace, by (service, worker)."""

    def __init__(self) -> None:
        self.processes: dict[tuple[str, str], HealthTotals] = {}

    def add(self, report: Health) -> None:
        """Take one report."""
        self.processes.setdefault((report.service, report.worker), HealthTotals()).add(report)

    def stopping(self, service: str, worker: str) -> bool:
        """Whether the latest report of `service/worker` says it is stopping."""
        process = self.processes.get((service, worker))
        last = process.last if process is not None else None
        return last is not None and last.state == ServiceState.STOPPING

    def totals(self, service: str, worker: str) -> HealthTotals:
        """Everything `service/worker` reported (empty if nothing)."""
        return self.processes.get((service, worker), HealthTotals()).totals()
