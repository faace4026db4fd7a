"""`hamnet replay FILE...`: publish a recording (`hamnet record`) back onto Zenoh, each
payload byte for byte on its recorded key moved into this command's `--namespace`, so the
monitor and perception work on it unchanged.

    hamnet replay runs/demo.mcap                    # at the recorded timing
    hamnet replay runs/demo.mcap --speed 4          # four times faster
    hamnet replay runs/demo.mcap --fast             # as fast as possible, in order
    hamnet replay runs/demo.mcap --step             # Enter: one step (state to state)
    hamnet replay runs/long-*.mcap --topics 'hamnet/*/sim/**' --namespace replayed

Files of one rotated recording, and the parts of a restarted recorder's sequence
(demo.mcap, demo.1.mcap, ...: give the first), are merged in log-time order; an unfinished file (recorder
killed) replays up to its last chunk. See docs/recorder.md.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import tyro

from hamnet.recorder.config import ReplayConfig
from hamnet.recorder.replay_shell import ReplayShell
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.numbered_files import recording_files
from hamnet.runtime.recordings import read_recording, summary_counts, unreadable
from hamnet.runtime.service import Service

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReplayServiceConfig:
    """Which recording to replay, and how."""

    files: Annotated[tuple[Path, ...], tyro.conf.Positional] = ()
    """MCAP files of one recording (e.g. runs/long-*.mcap); the first file of a sequence
    (runs/demo.mcap) stands for every part of it (runs/demo.1.mcap, ...)."""
    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    replay: Annotated[ReplayConfig, Flattened] = field(default_factory=ReplayConfig)


CONFIG = ReplayServiceConfig
"""The config `hamnet replay` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet replay` with command-line arguments `argv`; returns the exit status."""
    config, identity = parse_service(CONFIG, argv, "replay", __doc__)
    files = recording_files(config.files)
    problem = unreadable(files)
    if problem:
        log.error("cannot replay: %s", problem)
        return 2
    # Totals for progress lines come from the files' summaries, when every file has one.
    expected = None if config.replay.topics else summary_counts(files)
    with Service(identity, config.common.transport) as service:
        messages = read_recording(files)
        return ReplayShell(service, config.replay, messages, expected).run()
