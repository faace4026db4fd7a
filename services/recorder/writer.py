"""Writes recorded payloads, unchanged, to chunked and compressed MCAP files.

Consumes (key, payload bytes, receive time, publish time) one message at a time; produces
MCAP files whose channels are the Zenoh keys, with the protobuf schema the topic contract
gives each key (`hamnet.runtime.contract.match_key`), so that standard MCAP readers
(the mcap CLI, Foxglove, Rerun) decode them. A key outside the contract is recorded on a
channel without schema (schema id 0, message encoding "") rather than dropped.

Crash safety: the writer closes each chunk itself (by size or age) and hands it to the
operating system at once, so a process killed even with SIGKILL leaves a file that the
standard sequential MCAP reader reads up to its last completed chunk (only the summary at
the end is missing). A write that fails (a full disk) raises OSError; `abandon` then cuts
the file back to its last complete chunk. Rotation starts a new self-contained file (its
own schemas and channels) by size or by the time it spans. Existing files are never
replaced: the recording goes to the next free part of the output's sequence
(`hamnet.runtime.numbered_files`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from mcap.well_known import MessageEncoding
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import register_schema

from hamnet import __version__
from hamnet.recorder.config import Compression, RecorderConfig
from hamnet.runtime.numbered_files import file_path, next_part
from hamnet.recorder.sink import FileSink
from hamnet.runtime.contract import match_key

COMPRESSION: dict[Compression, CompressionType] = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}

RAW_ENCODING = ""
"""Message encoding of channels for keys outside the contract (no schema, raw bytes)."""

PROFILE = "hamnet"
"""MCAP header profile of every recording."""

LIBRARY = f"hamnet-recorder/{__version__}"
"""MCAP header library of every recording."""

NEVER = 1 << 62
"""Chunk size handed to the mcap writer: it never closes a chunk itself (we do, see
`RecordingWriter._close_chunk`), so every chunk reaches the file the moment it is closed."""


def default_output(start_ns: int) -> Path:
    """`runs/record/<UTC date-time>.mcap` for a recording started at `start_ns` (Unix ns)."""
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime(start_ns / 1e9))
    return Path("runs") / "record" / f"{stamp}.mcap"


@dataclass
class _OpenFile:
    """The file being written and what it already holds."""

    path: Path
    stream: FileSink
    writer: Writer
    opened_ns: int
    channels: dict[str, int] = field(default_factory=dict)
    """Channel id of each key in this file."""
    schemas: dict[str, int] = field(default_factory=dict)
    """Schema id of each protobuf type in this file."""


class RecordingWriter:
    """One recording: one MCAP file, or numbered files when it rotates."""

    def __init__(self, config: RecorderConfig, metadata: dict[str, str], start_ns: int) -> None:
        """Open the first file at once, so a bad output path fails before anything is
        received.

        Args:
            config: chunking, compression, rotation and output.
            metadata: written to every file as the MCAP metadata record "hamnet".
            start_ns: Unix time of the start, ns (names the default output).
        """
        self.config = config
        self.metadata = dict(metadata)
        self.requested = config.output or default_output(start_ns)
        """The output asked for; `output` differs when that one already exists."""
        self.requested.parent.mkdir(parents=True, exist_ok=True)
        self.output = next_part(self.requested)
        """The part of the output's sequence this recording writes."""
        self.paths: list[Path] = []
        """Every file of the recording so far, in order."""
        self.messages = 0
        """Messages written so far, all files."""
        self.payload_bytes = 0
        """Payload bytes written so far, all files."""
        self._sequence: dict[str, int] = {}
        self._pending_bytes = 0
        self._chunk_opened_ns: int | None = None
        self._file: _OpenFile | None = None
        try:
            self._open(start_ns)
        except OSError:
            self.abandon()  # no empty or torn file left behind
            raise

    def write(self, key: str, payload: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        """Append one message, unchanged.

        Args:
            key: the Zenoh key it arrived on (the MCAP channel topic).
            payload: its bytes.
            log_time_ns: when it was received, Unix ns.
            publish_time_ns: when it was published (header stamp), Unix ns.
        """
        self._maybe_rotate(log_time_ns)  # a file spans less than rotate_s
        if self._file is None:
            self._file = self._open(log_time_ns)
        sequence = self._sequence.get(key, 0)
        self._sequence[key] = sequence + 1
        self._file.writer.add_message(
            channel_id=self._channel(key),
            log_time=log_time_ns,
            data=payload,
            publish_time=publish_time_ns,
            sequence=sequence,
        )
        self.messages += 1
        self.payload_bytes += len(payload)
        self._pending_bytes += len(payload)
        if self._chunk_opened_ns is None:
            self._chunk_opened_ns = log_time_ns
        if self._pending_bytes >= self.config.chunk_bytes:
            self._close_chunk()
        self._maybe_rotate(log_time_ns)

    def poll(self, now_ns: int) -> None:
        """Close the open chunk when it is `chunk_s` old, and rotate when due; call this
        regularly, also while nothing arrives, so a quiet stream still reaches the file.

        Args:
            now_ns: the current Unix time, ns (the clock of the log times).
        """
        opened = self._chunk_opened_ns
        if opened is not None and now_ns - opened >= self.config.chunk_s * 1e9:
            self._close_chunk()
        self._maybe_rotate(now_ns)

    def close(self) -> None:
        """Finish the current file (last chunk, indexes, summary, footer).

        Raises:
            OSError: the file could not be finished (call `abandon`).
        """
        if self._file is not None:
            self._finish(self._file)
            self._file = None

    def abandon(self) -> None:
        """Stop after a failed write: close the current file without writing more, cut back
        to its last complete chunk (what it holds stays readable, without a summary)."""
        if self._file is not None:
            if self._file.stream.abandon():
                self.paths.remove(self._file.path)  # it held nothing: no empty file is left
            self._file = None

    def _open(self, now_ns: int) -> _OpenFile:
        path = file_path(self.output, self.config.rotates, len(self.paths))
        stream = FileSink(path)
        self.paths.append(path)
        self._file = _OpenFile(path, stream, Writer(
            stream, chunk_size=NEVER, compression=COMPRESSION[self.config.compression]), now_ns)
        self._file.writer.start(profile=PROFILE, library=LIBRARY)
        self._file.writer.add_metadata("hamnet", {**self.metadata, "file_index": str(len(self.paths) - 1)})
        self._file.writer.flush()
        return self._file

    def _channel(self, key: str) -> int:
        """Channel id of `key` in the current file, registering it (and its schema) first."""
        file = self._file
        if key in file.channels:
            return file.channels[key]
        topic = match_key(key)
        if topic is None or topic.message is None:
            schema_id, encoding = 0, RAW_ENCODING
        else:
            name = topic.message.DESCRIPTOR.full_name
            if name not in file.schemas:
                file.schemas[name] = register_schema(file.writer, topic.message)
            schema_id, encoding = file.schemas[name], MessageEncoding.Protobuf
        file.channels[key] = file.writer.register_channel(key, encoding, schema_id)
        return file.channels[key]

    def _close_chunk(self) -> None:
        """Compress and write the open chunk and hand it to the OS (no fsync: the page
        cache survives the death of the process, which is what SIGKILL safety needs)."""
        self._file.writer.flush()
        self._pending_bytes = 0
        self._chunk_opened_ns = None

    def _maybe_rotate(self, now_ns: int) -> None:
        file = self._file
        if file is None or not self.config.rotates:
            return
        size = file.stream.tell() + self._pending_bytes  # compressed so far + open chunk
        too_big = self.config.rotate_bytes and size >= self.config.rotate_bytes
        too_long = self.config.rotate_s and now_ns - file.opened_ns >= self.config.rotate_s * 1e9
        if too_big or too_long:
            self._finish(file)
            self._file = None  # the next message opens the next file: no empty files

    def _finish(self, file: _OpenFile) -> None:
        file.writer.finish()
        file.stream.close()  # a failure leaves it open for `abandon`
        self._pending_bytes = 0
        self._chunk_opened_ns = None
