"""Reads recordings back: every message of one or more MCAP files, in log-time order, those
of chosen key expressions (`selected`), at their recorded pace (`ReplayClock`).

Consumes MCAP files of `hamnet record` (finished, or cut short by a crash); produces
`RecordedMessage`s with the exact payload bytes and key each was recorded with, for the
recorder's replay and info and the camera's replay source. Files are read front to back with
the standard sequential reader (`mcap.stream_reader.StreamReader`), which needs no summary:
a file whose recorder was killed reads up to its last completed chunk, and the reason it
ends early is kept in its `FileContents`.
"""

from __future__ import annotations

import heapq
import struct
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import zenoh
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk


@dataclass(frozen=True)
class RecordedMessage:
    """One recorded message."""

    key: str
    """The Zenoh key it was received on (the MCAP channel topic)."""
    payload: bytes
    """Its bytes, exactly as received."""
    log_time_ns: int
    """When the recorder received it, Unix ns."""
    publish_time_ns: int
    """When it was published (its header stamp, else the receive time), Unix ns."""
    schema: str
    """Protobuf type of its channel, e.g. `hamnet.RobotState`; "" for raw channels."""


@dataclass
class FileContents:
    """What reading one file found, besides its messages (filled while it is read)."""

    path: Path
    size_bytes: int = 0
    """File size on disk."""
    chunks: int = 0
    """Completed chunks read."""
    compression: set[str] = field(default_factory=set)
    """Chunk compressions seen ("" for uncompressed)."""
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    """MCAP metadata records by name."""
    complete: bool = False
    """Whether the footer was reached (False: the writer never finished it, e.g. a crash)."""
    stopped: str = ""
    """Why reading stopped before the footer (truncated chunk, corrupt record...)."""


MAGIC = b"\x89MCAP0\r\n"
"""The 8 bytes every MCAP file starts with."""


def unreadable(paths: Sequence[Path]) -> str:
    """Why `paths` cannot be read as a recording, in one line; '' when they can (each exists
    and starts with the MCAP magic; a file cut short later on still reads to its last chunk).
    """
    if not paths:
        return "give at least one file"
    missing = [str(path) for path in paths if not path.is_file()]
    if missing:
        return f"no such file: {', '.join(missing)}"
    for path in paths:
        try:
            with open(path, "rb") as stream:
                start = stream.read(len(MAGIC))
        except OSError as error:
            return f"cannot read {path}: {error.strerror}"
        if start != MAGIC:
            return f"{path} is not an MCAP file (it does not start with the MCAP magic)"
    return ""


def read_file(path: Path, contents: FileContents | None = None) -> Iterator[RecordedMessage]:
    """Every message of one MCAP file, in file order, up to its last readable record.

    Args:
        path: the file.
        contents: filled with what else the file holds, as reading goes.
    """
    contents = contents if contents is not None else FileContents(path)
    contents.size_bytes = path.stat().st_size
    schemas: dict[int, str] = {}
    channels: dict[int, Channel] = {}
    with open(path, "rb") as stream:
        records = StreamReader(stream, emit_chunks=True).records
        try:
            for record in records:
                if isinstance(record, Chunk):
                    contents.chunks += 1
                    contents.compression.add(record.compression)
                    inner = breakup_chunk(record, validate_crc=True)
                else:
                    inner = [record]
                for item in inner:
                    if isinstance(item, Schema):
                        schemas[item.id] = item.name
                    elif isinstance(item, Channel):
                        channels[item.id] = item
                    elif isinstance(item, Message):
                        channel = channels[item.channel_id]
                        yield RecordedMessage(
                            channel.topic,
                            item.data,
                            item.log_time,
                            item.publish_time,
                            schemas.get(channel.schema_id, ""),
                        )
                    elif isinstance(item, Metadata):
                        contents.metadata[item.name] = dict(item.metadata)
                    elif isinstance(item, Footer):
                        contents.complete = True
        except (
            McapError,
            struct.error,
            ValueError,
            KeyError,
        ) as error:  # truncated or corrupt tail
            contents.stopped = f"{type(error).__name__}: {error}".rstrip(": ")


def read_recording(
    paths: Sequence[Path], contents: list[FileContents] | None = None
) -> Iterator[RecordedMessage]:
    """Every message of several files (e.g. the rotated files of one recording) merged
    by log time; a recording in one file comes out in file order.

    Args:
        paths: the files.
        contents: one `FileContents` per file is appended here, filled as reading goes.
    """
    streams: list[Iterable[RecordedMessage]] = []
    for path in paths:
        found = FileContents(path)
        if contents is not None:
            contents.append(found)
        streams.append(read_file(path, found))
    if len(streams) == 1:
        return iter(streams[0])
    return heapq.merge(*streams, key=lambda message: message.log_time_ns)


def summary_counts(paths: Sequence[Path]) -> tuple[int, int, int] | None:
    """(messages, first log time, last log time) from the files' summaries, without reading
    their messages; None when any file has no summary (unfinished) or no messages."""
    total, first, last = 0, None, None
    for path in paths:
        with open(path, "rb") as stream:
            try:
                summary = make_reader(stream).get_summary()
            except (McapError, ValueError, OSError):
                return None
        if summary is None or summary.statistics is None:
            return None
        statistics = summary.statistics
        if statistics.message_count == 0:
            continue
        total += statistics.message_count
        first = min(statistics.message_start_time, first or statistics.message_start_time)
        last = max(statistics.message_end_time, last or 0)
    return None if first is None else (total, first, last)


def selected(
    messages: Iterable[RecordedMessage], topics: tuple[str, ...]
) -> Iterator[RecordedMessage]:
    """The messages whose recorded key matches one of the key expressions `topics` (all of
    them when `topics` is empty)."""
    if not topics:
        yield from messages
        return
    filters = [zenoh.KeyExpr(expr) for expr in topics]
    verdicts: dict[str, bool] = {}
    for message in messages:
        if message.key not in verdicts:
            key = zenoh.KeyExpr(message.key)
            verdicts[message.key] = any(f.intersects(key) for f in filters)
        if verdicts[message.key]:
            yield message


@dataclass(frozen=True)
class ReplayClock:
    """Maps recorded log times onto a monotonic wall clock, scaled by a speed factor."""

    first_log_ns: int
    """Log time of the first message replayed, Unix ns."""
    start_s: float
    """time.monotonic() at which that first message is due, s."""
    speed: float
    """Recorded seconds per wall-clock second (2.0: twice as fast)."""

    def due_s(self, log_time_ns: int) -> float:
        """time.monotonic() at which the message logged at `log_time_ns` is due, s."""
        return self.start_s + (log_time_ns - self.first_log_ns) / 1e9 / self.speed
