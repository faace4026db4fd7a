"""The lifecycle every service shares: open the session, hold a liveliness token, publish
health, stop gracefully on SIGINT/SIGTERM, and close everything in order.

A shell reads like a dora node:

    with Service(ServiceIdentity("echo", "0"), transport) as service:
        service.inbox.subscribe("state", key, RobotState)
        out = service.publisher(key_out)
        while service.running:
            received = service.receive(timeout=0.1)
            ...
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from types import FrameType, TracebackType

import zenoh

from hamnet.proto.health_pb2 import DropCount, Health, ServiceState
from hamnet.runtime import contract
from hamnet.runtime.ports import Ports
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher, Received
from hamnet.runtime.transport import TransportConfig, open_session

log = logging.getLogger(__name__)

SUPERVISOR_PID_ENV = "HAMNET_SUPERVISOR_PID"
"""Set by `hamnet up` for its children: they stop when that process is gone, so a launcher
killed with SIGKILL leaves nothing behind."""

EXIT_NO_RESTART = 74
"""Exit status of a service that stopped on a fault a restart cannot fix (EX_IOERR of
sysexits.h: its output cannot be written, e.g. the disk is full): `hamnet up` does not
restart it, it fails at once."""

ALIVE = contract.topic("alive/<service>/<w>")
HEALTH = contract.topic("health/<service>/<w>")


@dataclass(frozen=True)
class ServiceIdentity:
    """Who a running service is on the network."""

    service: str
    """Service name, e.g. `sim`."""
    worker: str = "0"
    """Worker id, so that several instances of one service can run side by side."""

    @property
    def source(self) -> str:
        """`service/worker`, as written in message headers and logs."""
        return f"{self.service}/{self.worker}"


class Service:
    """Session, liveliness token, health reports and signal handling of one service."""

    def __init__(
        self,
        identity: ServiceIdentity,
        transport: TransportConfig,
        health_period_s: float = 1.0,
        inbox_capacity: int = 1024,
        remap: Sequence[str] = (),
    ) -> None:
        """`remap`: `PORT=KEY` entries that rewire the shell's ports (`ports`)."""
        self.identity = identity
        self.transport = transport
        self.remap = tuple(remap)
        self.drops = DropCounter()
        self.events: Counter[str] = Counter()
        """Notable events by name since the start (`count_event`), in every health report."""
        self.figures: dict[str, float] = {}
        """Measured figures by name (`set_figure`), carried by every health report."""
        self.health_period_s = health_period_s
        self._inbox_capacity = inbox_capacity
        self._stop = threading.Event()
        self._publishers: dict[str, Publisher] = {}
        self._started = time.monotonic()
        self._loops = 0
        self._last_health = (self._started, 0)
        self.session: zenoh.Session | None = None
        self.inbox: Inbox | None = None
        self._token: zenoh.LivelinessToken | None = None
        self._health: Publisher | None = None
        self._previous_handlers: dict[int, object] = {}
        supervisor = os.environ.get(SUPERVISOR_PID_ENV)
        self._supervisor_pid = int(supervisor) if supervisor else None

    @property
    def namespace(self) -> str:
        """The stack namespace every key of this service lives in."""
        return self.transport.namespace

    def __enter__(self) -> Service:
        self._install_signal_handlers()
        self.session = open_session(self.transport)
        self.inbox = Inbox(self.session, self.drops, self._inbox_capacity)
        fields = {"service": self.identity.service, "w": self.identity.worker}
        health_key = HEALTH.key(self.namespace, **fields)
        self._health = Publisher(self.session, health_key, self.identity.source)
        self._publish_health(ServiceState.STARTING)
        # The token comes last: whoever sees it can rely on the service being ready.
        self._token = self.session.liveliness().declare_token(ALIVE.key(self.namespace, **fields))
        log.info("%s up in namespace %r", self.identity.source, self.namespace)
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self._stop.set()
        # Stopping is said before the token goes, so the launcher reads the withdrawal as a
        # stop, not as a hang (`hamnet.launcher.tokens`).
        if self._health is not None:
            self._publish_health(ServiceState.STOPPING)
        if self._token is not None:
            self._token.undeclare()
        if self.inbox is not None:
            self.inbox.close()
        for publisher in self._publishers.values():
            publisher.close()
        if self.session is not None:
            self.session.close()
        self._restore_signal_handlers()
        log.info("%s stopped (dropped payloads: %d)", self.identity.source, self.drops.total)

    @property
    def running(self) -> bool:
        """False once a stop was requested (signal or `stop()`)."""
        return not self._stop.is_set()

    def stop(self) -> None:
        """Ask the run loop to finish."""
        self._stop.set()

    def ports(self, ports: Ports) -> dict[str, str]:
        """The key of each of a shell's `ports`: its own in this namespace for this worker,
        or where `remap` rewires it."""
        return ports.keys(self.namespace, self.remap, w=self.identity.worker)

    def publisher(self, key: str) -> Publisher:
        """The publisher of `key` (declared on first use, closed with the service)."""
        if key not in self._publishers:
            self._publishers[key] = Publisher(self.session, key, self.identity.source)
        return self._publishers[key]

    def count_event(self, name: str, count: int = 1) -> None:
        """Count `count` `name` events (e.g. the sim's `loop_stalls`): health reports carry
        the totals, and `hamnet up` sums them in its summary."""
        self.events[name] += count

    def set_figure(self, name: str, value: float) -> None:
        """Report a measured figure (e.g. a latency percentile) in the next health reports."""
        self.figures[name] = value

    def receive(self, timeout: float = 0.1) -> Received | None:
        """Next message for the run loop; publishes health when it is due."""
        self.heartbeat()
        return self.inbox.get(timeout)

    def heartbeat(self) -> None:
        """One turn of the run loop: publish health when it is due, and stop when the launcher
        is gone. `receive` does it; a loop that waits on something else calls it."""
        self._loops += 1
        if time.monotonic() - self._last_health[0] >= self.health_period_s:
            self._publish_health(ServiceState.RUNNING)
            self._check_supervisor()

    def _check_supervisor(self) -> None:
        """Stop when the launcher that started this process is gone (we were re-parented)."""
        if self._supervisor_pid is not None and os.getppid() != self._supervisor_pid:
            log.warning(
                "%s: its launcher (pid %d) is gone, stopping",
                self.identity.source,
                self._supervisor_pid,
            )
            self._stop.set()

    def _publish_health(self, state: int) -> None:
        now = time.monotonic()
        then, loops = self._last_health
        report = Health(
            service=self.identity.service,
            worker=self.identity.worker,
            state=state,
            uptime_s=now - self._started,
            loop_rate_hz=(self._loops - loops) / max(now - then, 1e-9),
        )
        if self.inbox is not None:
            report.received.update(self.inbox.received)
        report.published.update({key: p.published for key, p in self._publishers.items()})
        report.events.update(self.events)
        report.figures.update(self.figures)
        report.drops.extend(
            DropCount(key=key, reason=reason, count=count)
            for (key, reason), count in sorted(self.drops.counts.items())
        )
        self._health.put(report)
        self._last_health = (now, self._loops)

    def _install_signal_handlers(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        for signum in (signal.SIGINT, signal.SIGTERM):
            self._previous_handlers[signum] = signal.signal(signum, self._on_signal)

    def _restore_signal_handlers(self) -> None:
        for signum, handler in self._previous_handlers.items():
            signal.signal(signum, handler)
        self._previous_handlers.clear()

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        log.info("%s received %s, stopping", self.identity.source, signal.Signals(signum).name)
        self._stop.set()
