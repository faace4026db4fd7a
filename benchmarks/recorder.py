"""Recorder benchmark: how fast recordings are written and read, and how much of a paced
stream a `hamnet record` process keeps.

Core (no networking): `RecordingWriter` writes N protobuf messages (a RobotState whose `q`
tensor holds float32 noise, the incompressible worst case of clouds and tokens) at payload
sizes 1 kB, 100 kB and 400 kB (a perception message), with zstd, lz4 and no compression,
against the baseline in the same run: the same payloads written with `file.write` (what any
recorder pays for the bytes alone). `read_file` reads the zstd recording back.

End to end: a `hamnet record` process on loopback Zenoh records a stream of 400 kB messages
published at fixed rates by this process; the figure is the fraction it recorded (the rest
was dropped somewhere: inbox overflow, counted in its Health, or the network).

Produces a table on stdout, progress on stderr and, as the last stdout line, one JSON
object: `write_mb_s_400k_zstd`, `write_mb_s_400k_lz4`, `baseline_mb_s_400k` (file.write),
`read_mb_s_400k_zstd`, `e2e_recorded_fraction` per rate, and every row under `results`.

    .venv/bin/python benchmarks/recorder.py --quick     # < 1 min on 2 cores
    .venv/bin/python benchmarks/recorder.py
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tyro

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import loopback_transport, progress, report, spawn, stop

from hamnet.proto.health_pb2 import Health
from hamnet.proto.sim_pb2 import RobotState
from hamnet.recorder.config import RecorderConfig
from hamnet.recorder.writer import RecordingWriter
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.recordings import read_file
from hamnet.runtime.tensor import to_tensor
from hamnet.runtime.transport import open_session

KEY = "hamnet/bench/sim/0/state"


@dataclass(frozen=True)
class RecorderBenchConfig:
    """What to measure and how much."""

    quick: bool = False
    """A short run for smoke tests, under a minute."""
    sizes_kb: tuple[int, ...] = (1, 100, 400)
    """Payload sizes, kB."""
    megabytes: float = 200.0
    """Payload MB written per row (quick: 20)."""
    rates_hz: tuple[float, ...] = (10.0, 50.0, 200.0)
    """End to end: publish rates of 400 kB messages (quick: 10 and 50)."""
    seconds: float = 5.0
    """End to end: seconds per rate (quick: 1.5)."""


def payloads(size_kb: int, count: int, seed: int = 0) -> list[bytes]:
    """`count` encoded RobotStates of about `size_kb` kB of float32 noise each."""
    rng = np.random.default_rng(seed)
    out = []
    for step in range(count):
        message = RobotState()
        message.header.step, message.header.stamp_ns = step, time.time_ns()
        noise = rng.standard_normal(size_kb * 256).astype(np.float32)  # (size_kb*256,) 4 B each
        message.q.CopyFrom(to_tensor(noise))
        out.append(message.SerializeToString())
    return out


def time_writer(directory: Path, data: list[bytes], compression: str) -> tuple[float, int]:
    """(seconds, file bytes) to record `data` and finish the file."""
    path = directory / f"{compression}.mcap"
    config = RecorderConfig(output=path, compression=compression, chunk_s=1e6)
    started = time.perf_counter()
    writer = RecordingWriter(config, {}, time.time_ns())
    t0 = time.time_ns()
    for index, payload in enumerate(data):
        writer.write(KEY, payload, t0 + index, t0 + index)
    writer.close()
    return time.perf_counter() - started, path.stat().st_size


def time_baseline(directory: Path, data: list[bytes]) -> float:
    """Seconds to write the same bytes with file.write."""
    started = time.perf_counter()
    with open(directory / "raw.bin", "wb") as stream:
        stream.writelines(data)
    return time.perf_counter() - started


def core_rows(config: RecorderBenchConfig, megabytes: float) -> list[dict]:
    rows = []
    for size_kb in config.sizes_kb:
        data = payloads(size_kb, max(10, int(megabytes * 1000 / size_kb)))
        total_mb = sum(map(len, data)) / 1e6
        with tempfile.TemporaryDirectory() as directory:
            folder = Path(directory)
            baseline = min(time_baseline(folder, data) for _ in range(3))
            rows.append({"size_kb": size_kb, "row": "file.write (baseline)",
                         "mb_s": total_mb / baseline, "us_per_message": baseline / len(data) * 1e6,
                         "ratio": 1.0})  # fmt: skip
            for compression in ("zstd", "lz4", "none"):
                seconds, size = min(time_writer(folder, data, compression) for _ in range(2))
                rows.append({"size_kb": size_kb, "row": f"write {compression}",
                             "mb_s": total_mb / seconds, "us_per_message": seconds / len(data) * 1e6,
                             "ratio": size / (total_mb * 1e6)})  # fmt: skip
            started = time.perf_counter()
            count = sum(1 for _ in read_file(folder / "zstd.mcap"))
            seconds = time.perf_counter() - started
            assert count == len(data)
            rows.append({"size_kb": size_kb, "row": "read zstd", "mb_s": total_mb / seconds,
                         "us_per_message": seconds / count * 1e6, "ratio": 1.0})  # fmt: skip
        progress(f"core {size_kb} kB done")
    return rows


def await_subscription(session, namespace: str) -> None:
    """Return once the recorder's Health shows it receives (probes on a key of their own)."""
    health = f"hamnet/{namespace}/health/record/0"
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("health", health, Health)
    probe = Publisher(session, f"hamnet/{namespace}/bench/probe", "bench/0")
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        probe.put_encoded(b"probe")
        received = inbox.get(timeout=0.2)
        if received is not None and sum(received.value.received.values()) > 0:
            break
    else:
        raise RuntimeError("the recorder never received anything")
    inbox.close()
    probe.close()


def end_to_end(rate_hz: float, seconds: float) -> dict:
    """Fraction of a paced stream of 400 kB messages that `hamnet record` wrote."""
    transport = loopback_transport()
    key = f"hamnet/{transport.namespace}/sim/0/state"
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / "e2e.mcap"
        recorder = spawn(["record", "-o", str(path)], transport)
        session = open_session(transport)
        publisher = Publisher(session, key, "bench/0")
        await_subscription(session, transport.namespace)
        data = payloads(400, 20)
        count = int(rate_hz * seconds)
        started = time.perf_counter()
        for index in range(count):
            delay = started + index / rate_hz - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            publisher.put_encoded(data[index % len(data)])
        time.sleep(1.0)
        stop([recorder])
        session.close()
        recorded = sum(1 for message in read_file(path) if message.key == key)
    progress(f"end to end {rate_hz} Hz done")
    return {"rate_hz": rate_hz, "mb_s": rate_hz * 0.4, "published": count, "recorded": recorded,
            "recorded_fraction": recorded / count}  # fmt: skip


def main() -> dict:
    config = tyro.cli(RecorderBenchConfig)
    megabytes = 20.0 if config.quick else config.megabytes
    rates = config.rates_hz[:2] if config.quick else config.rates_hz
    seconds = 1.5 if config.quick else config.seconds
    rows = core_rows(config, megabytes)
    e2e = [end_to_end(rate, seconds) for rate in rates]
    print(f"{'size':>6}  {'row':<22} {'MB/s':>8} {'us/msg':>9} {'file/payload':>12}")
    for row in rows:
        print(f"{row['size_kb']:>4}kB  {row['row']:<22} {row['mb_s']:>8.1f} "
              f"{row['us_per_message']:>9.1f} {row['ratio']:>12.3f}")  # fmt: skip
    for row in e2e:
        print(f"hamnet record at {row['rate_hz']:.0f} Hz x 400 kB ({row['mb_s']:.0f} MB/s): "
              f"{row['recorded']}/{row['published']} recorded")  # fmt: skip
    at = {(row["size_kb"], row["row"]): row["mb_s"] for row in rows}
    return {
        "mode": "quick" if config.quick else "full",
        "write_mb_s_400k_zstd": at[(400, "write zstd")],
        "write_mb_s_400k_lz4": at[(400, "write lz4")],
        "baseline_mb_s_400k": at[(400, "file.write (baseline)")],
        "read_mb_s_400k_zstd": at[(400, "read zstd")],
        "e2e_recorded_fraction": {
            f"{row['rate_hz']:.0f}Hz": row["recorded_fraction"] for row in e2e
        },
        "results": rows,
        "end_to_end": e2e,
    }


if __name__ == "__main__":
    report(main())
