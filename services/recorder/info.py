"""`hamnet record info`: what a recording holds, per topic and per file.

Consumes MCAP files (one recording, possibly rotated, finished or cut short by a crash);
produces a `RecordingInfo` (topics with message counts, rates and sizes; duration; files
with their size, chunks, compression and whether they were finished), as text or JSON.
Everything is counted by reading the messages, so unfinished files report what they hold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from hamnet.runtime.recordings import FileContents, read_recording


@dataclass(frozen=True)
class TopicInfo:
    """One recorded key."""

    key: str
    schema: str
    """Protobuf type, or "" for a raw channel (a key outside the contract)."""
    messages: int
    payload_bytes: int
    first_ns: int
    """Log time of its first message, Unix ns."""
    last_ns: int
    """Log time of its last message, Unix ns."""

    @property
    def rate_hz(self) -> float:
        """Messages per second between its first and last message (0 for one message)."""
        span = (self.last_ns - self.first_ns) / 1e9
        return (self.messages - 1) / span if span > 0 else 0.0


@dataclass(frozen=True)
class FileInfo:
    """One file of the recording."""

    path: str
    size_bytes: int
    chunks: int
    compression: str
    """Chunk compression(s), comma-separated; "none" for uncompressed chunks."""
    complete: bool
    """False for a file whose writer never finished it (crash): read up to its last chunk."""
    stopped: str
    """Why reading stopped before its end, for an unfinished file."""


@dataclass(frozen=True)
class RecordingInfo:
    """A whole recording."""

    topics: tuple[TopicInfo, ...]
    files: tuple[FileInfo, ...]

    @property
    def messages(self) -> int:
        return sum(t.messages for t in self.topics)

    @property
    def duration_s(self) -> float:
        """From the first to the last message, s (log time)."""
        if not self.topics:
            return 0.0
        return (max(t.last_ns for t in self.topics) - min(t.first_ns for t in self.topics)) / 1e9

    def to_json(self) -> dict:
        """Plain data for `--json` (rates and totals included)."""
        return {
            "messages": self.messages,
            "duration_s": self.duration_s,
            "size_bytes": sum(f.size_bytes for f in self.files),
            "complete": all(f.complete for f in self.files),
            "topics": [{**vars(t), "rate_hz": t.rate_hz} for t in self.topics],
            "files": [vars(f) for f in self.files],
        }


def summarise(paths: Sequence[Path]) -> RecordingInfo:
    """Read every message of `paths` and count them per key."""
    contents: list[FileContents] = []
    tally: dict[str, list] = {}  # key -> [schema, messages, bytes, first_ns, last_ns]
    for message in read_recording(paths, contents):
        entry = tally.setdefault(message.key, [message.schema, 0, 0, message.log_time_ns, 0])
        entry[1] += 1
        entry[2] += len(message.payload)
        entry[3] = min(entry[3], message.log_time_ns)
        entry[4] = max(entry[4], message.log_time_ns)
    topics = tuple(TopicInfo(key, *entry) for key, entry in sorted(tally.items()))
    files = tuple(
        FileInfo(
            str(c.path),
            c.size_bytes,
            c.chunks,
            ",".join(sorted(x or "none" for x in c.compression)),
            c.complete,
            c.stopped,
        )
        for c in contents
    )
    return RecordingInfo(topics, files)


def format_text(info: RecordingInfo) -> str:
    """The human-readable report."""
    size = sum(f.size_bytes for f in info.files)
    payload = sum(t.payload_bytes for t in info.topics)
    lines = [
        f"messages  {info.messages} on {len(info.topics)} topics over {info.duration_s:.3f} s",
        f"size      {_bytes(size)} on disk, {_bytes(payload)} of payloads",
        "",
    ]
    width = max((len(t.key) for t in info.topics), default=5)
    lines.append(f"{'topic':<{width}}  {'messages':>8}  {'rate Hz':>8}  {'payloads':>10}  schema")
    for t in info.topics:
        lines.append(
            f"{t.key:<{width}}  {t.messages:>8}  {t.rate_hz:>8.2f}  {_bytes(t.payload_bytes):>10}"
            f"  {t.schema or '(raw, no schema)'}"
        )
    lines.append("")
    for f in info.files:
        state = "finished" if f.complete else f"UNFINISHED (read to its last chunk: {f.stopped})"
        lines.append(
            f"{f.path}: {_bytes(f.size_bytes)}, {f.chunks} chunks ({f.compression}), {state}"
        )
    return "\n".join(lines)


def _bytes(count: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= scale:
            return f"{count / scale:.1f} {unit}"
    return f"{count} B"
