"""`hamnet record`: record topics of the stack to MCAP, byte for byte, with the protobuf
schema of each topic (readable by the mcap CLI, Foxglove and Rerun).

    hamnet record -o runs/demo.mcap                      # every key of the namespace
    hamnet record --key-exprs 'hamnet/default/sim/**'    # only the sim's topics
    hamnet record --rotate-mb 500 -o runs/long.mcap      # long-0000.mcap, long-0001.mcap...
    hamnet record -o runs/demo.mcap                      # again: runs/demo.1.mcap (never replaced)
    hamnet record info runs/demo.mcap [--json]           # topics, counts, rates, duration

Stop it with Ctrl-C (or SIGTERM): the file is finished. Killed harder, it still reads up to
its last chunk (`--chunk-s`). Replay with `hamnet replay`. See docs/recorder.md.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

from hamnet import __version__
from hamnet.recorder.config import RecorderConfig
from hamnet.recorder.record_shell import RecordShell
from hamnet.recorder.writer import RecordingWriter
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import EXIT_NO_RESTART, Service

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RecordServiceConfig:
    """What to record, where, and for how long."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    recorder: Annotated[RecorderConfig, Flattened] = field(default_factory=RecorderConfig)
    key_exprs: tuple[str, ...] = ()
    """Zenoh key expressions to record; empty: every key of the namespace (hamnet/<ns>/**).
    Keys outside the topic contract are recorded as raw channels without schema."""
    duration_s: float = 0.0
    """Stop after this many seconds (0: until stopped)."""
    report_period_s: float = 5.0
    """Seconds between progress lines."""
    queue_size: int = 1024
    """Payloads held between Zenoh and the writer; when full, the oldest is dropped and
    counted (`overflow` in Health): the recorder never blocks the network."""

    def __post_init__(self) -> None:
        if self.queue_size < 1 or self.duration_s < 0 or not self.report_period_s > 0:
            raise ValueError("queue_size must be >= 1, duration_s >= 0, report_period_s > 0")


CONFIG = RecordServiceConfig
"""The config `hamnet record` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet record` (or `hamnet record info`) with arguments `argv`; returns the exit
    status."""
    if argv and argv[0] == "info":
        from hamnet.recorder.info_cli import main as info_main

        return info_main(argv[1:])
    config, identity = parse_service(CONFIG, argv, "record", __doc__)
    start_ns = time.time_ns()
    metadata = {
        "namespace": config.common.transport.namespace,
        "key_exprs": " ".join(config.key_exprs),
        "hamnet_version": __version__,
        "recorder": identity.source,
        "start_ns": str(start_ns),
    }
    try:
        writer = RecordingWriter(config.recorder, metadata, start_ns)
    except OSError as error:
        log.error(
            "cannot record to %s: %s",
            error.filename or config.recorder.output,
            error.strerror or error,
        )
        return EXIT_NO_RESTART
    if writer.output != writer.requested:
        log.warning(
            "%s exists: recording to %s (a recording never replaces a file)",
            writer.requested,
            writer.output,
        )
    try:
        with Service(
            identity, config.common.transport, inbox_capacity=config.queue_size
        ) as service:
            shell = RecordShell(
                service, writer, config.key_exprs, config.duration_s, config.report_period_s
            )
            return shell.run()
    finally:
        writer.abandon()  # only when the service failed to start: run() ends the file
