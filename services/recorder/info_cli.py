"""`hamnet record info FILE...`: summarise a recording (one file, the parts of a restarted
recorder's sequence, or the rotated files of one recording): topics with message counts, rates and sizes, duration, files with their
size, chunks and compression, and whether each was finished (a recorder killed mid-file
leaves a file read up to its last chunk)."""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import tyro

from hamnet.recorder.info import format_text, summarise
from hamnet.runtime.cli import parse
from hamnet.runtime.numbered_files import recording_files
from hamnet.runtime.recordings import unreadable


@dataclass(frozen=True)
class InfoConfig:
    """Which recording to summarise and how to print it."""

    files: Annotated[tuple[Path, ...], tyro.conf.Positional]
    """MCAP files of one recording (e.g. runs/long-*.mcap); the first file of a sequence
    (runs/demo.mcap) stands for every part of it (runs/demo.1.mcap, ...)."""
    json: bool = False
    """Print one JSON object instead of text."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet record info` with arguments `argv`; returns the exit status."""
    config = parse(InfoConfig, argv, "hamnet record info", __doc__)
    files = recording_files(config.files)
    problem = unreadable(files)
    if problem:
        print(f"hamnet record info: {problem}", file=sys.stderr)
        return 2
    info = summarise(files)
    print(json.dumps(info.to_json()) if config.json else format_text(info))
    return 0
