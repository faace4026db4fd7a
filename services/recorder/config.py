"""Configuration of the recorder and of replay: one frozen dataclass each.

`RecorderConfig` says where recordings go and how they are cut into chunks (the unit that
survives a crash) and files (rotation); `ReplayConfig` says how recorded messages go back
onto Zenoh (timing, filters).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import tyro

Compression = Literal["zstd", "lz4", "none"]
"""How each MCAP chunk is compressed (both codecs come with the `mcap` package)."""

MB = 1_000_000
"""Bytes in one of the MB of `--chunk-mb` and `--rotate-mb`."""


@dataclass(frozen=True)
class RecorderConfig:
    """Where a recording goes, its chunks and its rotation."""

    output: Annotated[Path | None, tyro.conf.arg(aliases=("-o",))] = None
    """Recording file. None: runs/record/<UTC date-time>.mcap. Never replaced: when it
    exists, the recording goes to <stem>.1.mcap, <stem>.2.mcap, ... (the first free part).
    With rotation, files are <stem>-0000.mcap, <stem>-0001.mcap, ... beside it. Replay and
    info given <stem>.mcap read every part and file."""
    compression: Compression = "zstd"
    """Chunk compression: zstd (smaller), lz4 (faster) or none."""
    chunk_mb: float = 1.0
    """A chunk is closed and written once its messages reach this many MB (uncompressed)."""
    chunk_s: float = 1.0
    """... or once it is this many seconds old: a crash (even SIGKILL) loses at most the
    messages of the open chunk, so at most this long of a slow stream."""
    rotate_mb: float = 0.0
    """Start a new file once the current one holds this many MB of data (0: never); its
    summary (indexes and schemas, a few kB) comes on top."""
    rotate_s: float = 0.0
    """Start a new file once the current one spans this many seconds (0: never)."""

    def __post_init__(self) -> None:
        if self.compression not in ("zstd", "lz4", "none"):
            raise ValueError(f"compression must be zstd, lz4 or none, got {self.compression!r}")
        if not (self.chunk_mb > 0 and self.chunk_s > 0):
            raise ValueError("chunk_mb and chunk_s must be > 0")
        if self.rotate_mb < 0 or self.rotate_s < 0:
            raise ValueError("rotate_mb and rotate_s must be >= 0 (0: no rotation)")
        if self.output is not None and self.output.suffix != ".mcap":
            raise ValueError(f"output must end in .mcap, got {self.output}")

    @property
    def rotates(self) -> bool:
        """Whether the recording is split into numbered files."""
        return self.rotate_mb > 0 or self.rotate_s > 0

    @property
    def chunk_bytes(self) -> int:
        """`chunk_mb` in bytes."""
        return int(self.chunk_mb * MB)

    @property
    def rotate_bytes(self) -> int:
        """`rotate_mb` in bytes (0: never)."""
        return int(self.rotate_mb * MB)


@dataclass(frozen=True)
class ReplayConfig:
    """How recorded messages go back onto Zenoh."""

    speed: float = 1.0
    """Replay at the recorded timing times this factor (2.0: twice as fast)."""
    fast: bool = False
    """As fast as possible, ignoring the recorded timing (order is kept)."""
    step: bool = False
    """Stepped: publish one step (see docs/recorder.md) per line read on stdin; an empty
    line advances one step, a number N advances N steps, `q` stops."""
    topics: tuple[str, ...] = ()
    """Replay only recorded keys matching one of these key expressions (e.g.
    'hamnet/*/sim/**'); empty: every key."""
    start_delay_s: float = 1.0
    """Wait this long after declaring the publishers before the first message, so that
    subscribers already running have their routes to it."""
    progress_s: float = 2.0
    """Seconds between progress lines."""

    def __post_init__(self) -> None:
        if not self.speed > 0:
            raise ValueError(f"speed must be > 0, got {self.speed} (use --fast for no timing)")
        if self.fast and self.step:
            raise ValueError("choose one of --fast and --step")
        if self.start_delay_s < 0 or not self.progress_s > 0:
            raise ValueError("start_delay_s must be >= 0 and progress_s > 0")
