"""`hamnet monitor --save` streams its recording to the file as it runs, so its memory does
not grow with the recording (issue 13: 23 MB a minute in a soak, about the .rrd's size).

Both tests run a free-running `hamnet sim` and the monitor as processes on real Zenoh. The
fast one watches the .rrd file grow while the monitor is still running (it is not written at
exit); the slow one samples the monitor's resident memory (/proc/<pid>/status) for minutes
and compares the growth with the file's."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from hamnet.runtime.transport import TransportConfig
from tests.conftest import transport_args
from tests.stack.up import rss_mb

SIM = ("sim", "--num-envs", "4", "--num-objects", "2", "--nthread", "1", "--realtime")


def wait_for_size(
    path: Path, size: int, processes: list[subprocess.Popen], timeout_s: float
) -> int:
    """Wait until `path` holds more than `size` bytes while every process runs; its size."""
    deadline = time.monotonic() + timeout_s
    while not (path.exists() and path.stat().st_size > size):
        for process in processes:
            assert process.poll() is None, process.stdout.read()
        assert time.monotonic() < deadline, f"{path} stayed at {size} bytes"
        time.sleep(0.2)
    return path.stat().st_size


def start(spawn, transport: TransportConfig, path: Path) -> list[subprocess.Popen]:
    """A free-running sim and a monitor saving to `path`."""
    sim = spawn(*SIM, *transport_args(transport))
    monitor = spawn("monitor", "--save", str(path), *transport_args(transport))
    return [sim, monitor]


def test_the_rrd_file_grows_while_the_monitor_runs(
    spawn, transport: TransportConfig, tmp_path
) -> None:
    path = tmp_path / "monitor.rrd"
    processes = start(spawn, transport, path)
    monitor = processes[1]
    size = wait_for_size(path, 0, processes, timeout_s=60)
    size = wait_for_size(path, size, processes, timeout_s=60)
    wait_for_size(path, size, processes, timeout_s=60)  # still growing: streamed, not kept
    os.killpg(monitor.pid, signal.SIGTERM)
    assert monitor.wait(timeout=10) == 0, monitor.stdout.read()


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_monitor_memory_stays_flat_while_its_recording_grows(spawn, transport, tmp_path) -> None:
    """After a minute of warm-up, the monitor's memory over five minutes grows by less than
    a quarter of what its file grows by (a monitor holding the recording grows by as much)."""
    path = tmp_path / "monitor.rrd"
    processes = start(spawn, transport, path)
    wait_for_size(path, 0, processes, timeout_s=60)
    time.sleep(60)
    samples: list[tuple[float, int]] = []
    for _ in range(31):
        for process in processes:
            assert process.poll() is None, process.stdout.read()
        samples.append((rss_mb(processes[1].pid), path.stat().st_size))
        time.sleep(10)
    grown_rss = samples[-1][0] - min(rss for rss, _ in samples[:6])
    grown_file = (samples[-1][1] - samples[0][1]) / 2**20
    assert grown_file > 10, samples
    assert grown_rss < grown_file / 4, samples
