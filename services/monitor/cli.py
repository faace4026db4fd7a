"""`hamnet monitor`: a live Rerun view of one sim worker's stack (robot, scene, clouds,
module activations, rewards, success rate, safety events, trainer metrics) for one
environment in focus (`--worker`, `--env`).

Outputs, any combination: `--spawn` (start a viewer), `--connect-viewer URL` (a running
viewer), `--serve-web` (a browser at http://localhost:9090), `--save FILE.rrd` (headless).
`--layout training` shows a training run's curves alone (its rollout workers publish no
scene to draw). It runs in its own process and drops frames rather than slowing the stack
(`--max-rate-hz`, `--inbox-capacity`); see docs/monitor.md.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

from hamnet.monitor.config import MonitorLoopConfig, OutputConfig, ViewConfig
from hamnet.monitor.outputs import add_footer, open_recording
from hamnet.monitor.shell import PORTS, MonitorShell
from hamnet.monitor.view import MonitorView
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service


@dataclass(frozen=True)
class MonitorServiceConfig:
    """One monitor: which worker and environment it watches (`--worker`, `--env`), where
    the view goes, and how it keeps up."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    view: Annotated[ViewConfig, Flattened] = field(default_factory=ViewConfig)
    output: Annotated[OutputConfig, Flattened] = field(default_factory=OutputConfig)
    loop: Annotated[MonitorLoopConfig, Flattened] = field(default_factory=MonitorLoopConfig)


CONFIG = MonitorServiceConfig
"""The config `hamnet monitor` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet monitor` with command-line arguments `argv`; returns the exit status."""
    config, identity = parse_service(CONFIG, argv, "monitor", __doc__, ports=PORTS)
    try:
        recording, saved = open_recording(config.output, config.view.layout)
    except ValueError as error:
        print(f"hamnet monitor: {error}", file=sys.stderr)
        return 2
    try:
        view = MonitorView(recording, config.view)
        with Service(
            identity,
            config.common.transport,
            remap=config.common.remap,
            inbox_capacity=config.loop.inbox_capacity,
        ) as service:
            return MonitorShell(service, view, config.loop).run()
    finally:
        recording.flush()
        recording.disconnect()
        if saved is not None:
            add_footer(saved)
