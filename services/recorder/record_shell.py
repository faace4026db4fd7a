"""The recorder's Zenoh shell: everything published on a set of key expressions goes,
byte for byte, into a `RecordingWriter`.

Consumes any key matching `key_exprs` (default: every key of the namespace), published by
other processes. Zenoh callbacks only enqueue the payload in the service's bounded inbox
(a full inbox drops its oldest payload and counts it as `overflow` in Health); the service
thread reads each payload's header stamp (the publish time) and writes it with its receive
time as log time. A payload on a contract key that is not its contract's message is counted
(`decode`) and dropped, so that every protobuf channel decodes with standard tools.

A write that fails (a full disk, an I/O error) stops the recording: one error line, the
file cut back to its last complete chunk (readable), exit status `EXIT_NO_RESTART`, which
`hamnet up` does not restart (a new recorder would fail the same way).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

from hamnet.recorder.headers import header_of
from hamnet.recorder.writer import RecordingWriter
from hamnet.runtime import keys
from hamnet.runtime.pubsub import Received
from hamnet.runtime.service import EXIT_NO_RESTART, Service

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Payload:
    """One received payload, as the inbox hands it to the service thread."""

    data: bytes
    stamp_ns: int
    """Its header stamp (publish time), Unix ns; 0 when it has none."""


def decode_payload(key: str, data: bytes) -> Payload:
    """Keep the payload unchanged; read its header stamp (PayloadError when a contract key
    carries something else than its message)."""
    header = header_of(key, data)
    return Payload(data, header.stamp_ns if header is not None else 0)


class RecordShell:
    """Subscribes, writes, reports progress; `run` returns the exit status."""

    def __init__(
        self,
        service: Service,
        writer: RecordingWriter,
        key_exprs: tuple[str, ...],
        duration_s: float = 0.0,
        report_period_s: float = 5.0,
    ) -> None:
        self.service, self.writer = service, writer
        self.key_exprs = key_exprs or (keys.namespace_pattern(service.namespace),)
        self.duration_s, self.report_period_s = duration_s, report_period_s
        # The inbox stamps arrivals with the monotonic clock; log times are Unix ns.
        self._wall_offset_ns = time.time_ns() - time.monotonic_ns()
        for index, key_expr in enumerate(self.key_exprs):
            # Remote only: the recorder's own health reports are not part of the stack.
            service.inbox.subscribe(
                f"record{index}", key_expr, decoder=decode_payload, remote_only=True
            )

    def run(self) -> int:
        """Record until stopped (signal, or `duration_s`), then finish the file; returns the
        exit status (`EXIT_NO_RESTART` after a failed write)."""
        writer = self.writer
        log.info("recording %s to %s", ", ".join(self.key_exprs), writer.paths[0])
        try:
            self._record()
            writer.close()
        except OSError as error:
            writer.abandon()
            log.error(
                "cannot write the recording (%s): stopped; %s reads up to its last complete chunk",
                error.strerror or error,
                ", ".join(map(str, writer.paths)),
            )
            return EXIT_NO_RESTART
        log.info(
            "recorded %d messages (%d payload bytes, %d dropped) in %s",
            writer.messages,
            writer.payload_bytes,
            self.service.drops.total,
            ", ".join(map(str, writer.paths)),
        )
        return 0

    def _record(self) -> None:
        service, writer = self.service, self.writer
        started = last_report = time.monotonic()
        reported = (0, 0)
        while service.running:
            now = time.monotonic()
            if self.duration_s and now - started >= self.duration_s:
                break
            received = service.receive(timeout=0.1)
            if received is not None:
                self._write(received)
            writer.poll(time.time_ns())
            if now - last_report >= self.report_period_s:
                reported = self._report(now - last_report, reported)
                last_report = now
        # What was received before the stop goes into the file too: every payload the
        # subscriptions counted is written or counted as dropped.
        while (received := service.inbox.get(timeout=0)) is not None:
            self._write(received)

    def _write(self, received: Received) -> None:
        log_time = received.received_ns + self._wall_offset_ns
        payload: Payload = received.value
        self.writer.write(received.key, payload.data, log_time, payload.stamp_ns or log_time)

    def _report(self, elapsed_s: float, before: tuple[int, int]) -> tuple[int, int]:
        writer = self.writer
        now = (writer.messages, writer.payload_bytes)
        log.info(
            "%d messages (%.1f/s, %.2f MB/s), dropped %d, writing %s",
            now[0],
            (now[0] - before[0]) / elapsed_s,
            (now[1] - before[1]) / elapsed_s / 1e6,
            self.service.drops.total,
            writer.paths[-1],
        )
        return now
