"""`hamnet record info FILE...`: summarise a recording (one file, or the rotated files of
one recording): topics with message counts, rates and sizes, duration, files with their
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


@dataclass(frozen=True)
class InfoConfig:
    """Which recording to summarise and how to print it."""

    files: Annotated[tuple[Path, ...], tyro.conf.Positional]
    """MCAP files of one recording (e.g. runs/long-*.mcap)."""
    json: bool = False
    """Print one JSON object instead of text."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet record info` with arguments `argv`; returns the exit status."""
    config = parse(InfoConfig, argv, "hamnet record info", __doc__)
    missing = [str(path) for path in config.files if not path.is_file()]
    if not config.files or missing:
        detail = f"no such file: {', '.join(missing)}" if missing else "give at least one file"
        print(f"hamnet record info: {detail}", file=sys.stderr)
        return 2
    info = summarise(config.files)
    print(json.dumps(info.to_json()) if config.json else format_text(info))
    return 0
