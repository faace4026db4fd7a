"""Names of a recording's files: the parts of a numbered sequence and, inside a part, the
files of a rotation.

Nothing that records replaces a file. When its output `run.mcap` exists (a recorder
restarted by `hamnet up`, a stack run again), it writes the next part of the sequence
instead: `run.mcap`, `run.1.mcap`, `run.2.mcap`, ... A rotating part is written as numbered
files beside it (`run-0000.mcap`, `run-0001.mcap`; in part 1: `run.1-0000.mcap`, ...).
Readers given the first file (the base name) read every part, and every part's files, in
order. The same names serve the monitor's Rerun file (`view.rrd`, `view.1.rrd`, ...) and
the launcher's list of what a run wrote.
"""

from __future__ import annotations

import glob
from collections.abc import Sequence
from pathlib import Path


def part_path(base: Path, index: int) -> Path:
    """Part `index` of the recording named `base`: `base` itself, then
    `<stem>.<index><suffix>` (`run.1.mcap`)."""
    return base if index == 0 else base.with_name(f"{base.stem}.{index}{base.suffix}")


def file_path(part: Path, rotates: bool, index: int) -> Path:
    """The `index`-th file of a part: the part itself, or `<stem>-<index:04d><suffix>` beside
    it when the recording rotates (names sort in recording order)."""
    return part.with_name(f"{part.stem}-{index:04d}{part.suffix}") if rotates else part


def part_files(part: Path) -> list[Path]:
    """The existing files of one part, in order: the part itself and its rotated files."""
    pattern = f"{glob.escape(part.stem)}-[0-9][0-9][0-9][0-9]{glob.escape(part.suffix)}"
    return ([part] if part.exists() else []) + sorted(part.parent.glob(pattern))


def next_part(base: Path) -> Path:
    """The first part of `base`'s sequence with no file yet: where a new recording goes.

    An output that exists but is not a regular file (a FIFO, a device) holds no recording
    to keep: it is written as it is.
    """
    if base.exists() and not base.is_file():
        return base
    index = 0
    while part_files(part_path(base, index)):
        index += 1
    return part_path(base, index)


def recording_files(paths: Sequence[Path]) -> list[Path]:
    """Every file of the recordings named by `paths`, in recording order, each once.

    A path that starts a sequence (its first file or its base name) stands for every part
    of it; a path with no file at all is kept as given, for the caller to report.
    """
    files: list[Path] = []
    for path in paths:
        found, index = [], 0
        while part := part_files(part_path(path, index)):
            found += part
            index += 1
        files += [f for f in found or [path] if f not in files]
    return files
