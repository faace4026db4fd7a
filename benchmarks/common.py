"""What every benchmark script does the same way: progress lines, timing calls, median and
p99 summaries, `hamnet` processes on a loopback network of their own, the figures' header
and the JSON line a run ends with.

Benchmarks run as scripts, so benchmarks/ is on sys.path and they import this as `common`.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from hamnet.launcher.argv import flags, forwarded
from hamnet.runtime.cli import CommonConfig
from hamnet.runtime.transport import TransportConfig, free_port


def progress(message: str) -> None:
    """One progress line on stderr, at once: stdout is kept for tables and the JSON line."""
    print(message, file=sys.stderr, flush=True)


def report(figures: dict) -> None:
    """Print `figures` as the run's last stdout line, the one tests/benchmarks read."""
    print(json.dumps(figures), flush=True)


def header(benchmark: str, quick: bool) -> dict[str, str]:
    """The first figures of a run: which benchmark, and whether it was a `--quick` one."""
    return {"benchmark": benchmark, "mode": "quick" if quick else "full"}


def print_header(line: str) -> None:
    """A table's header line on stdout, underlined to its width."""
    print(line)
    print("-" * len(line))


def timer(function: Callable[..., object]) -> Callable[..., float]:
    """A call that runs `function(*args)` and returns the seconds it took, nothing else
    (inputs are prepared outside it, so they are not timed)."""

    def call(*args: object) -> float:
        started = time.perf_counter_ns()
        function(*args)
        return (time.perf_counter_ns() - started) * 1e-9

    return call


def durations(function: Callable[[], object], repetitions: int, warmup: int = 1) -> np.ndarray:
    """Seconds of each of `repetitions` calls of `function`, (repetitions,), after `warmup`
    untimed calls (first calls pay for caches, allocations and lazy imports)."""
    for _ in range(warmup):
        function()
    call = timer(function)
    return np.array([call() for _ in range(repetitions)])


def median_p99(values: Iterable[float], scale: float = 1.0) -> tuple[float, float]:
    """Median and 99th percentile of `values` times `scale` (e.g. 1e3: seconds to ms): the
    typical cost and the tail a real-time budget must also hold."""
    scaled = np.asarray(list(values), dtype=np.float64) * scale
    return float(np.median(scaled)), float(np.percentile(scaled, 99))


def summary(
    values: Iterable[float], unit: str, scale: float = 1.0, digits: int | None = None
) -> dict[str, float]:
    """`{"median_<unit>": ..., "p99_<unit>": ...}` of `values` times `scale`, rounded to
    `digits` decimals when given."""
    median, p99 = median_p99(values, scale)
    if digits is not None:
        median, p99 = round(median, digits), round(p99, digits)
    return {f"median_{unit}": median, f"p99_{unit}": p99}


def loopback_transport(prefix: str = "bench", **fields: object) -> TransportConfig:
    """A transport of its own: a fresh namespace and a free rendezvous port on loopback, so
    that a run never sees another's traffic; `fields` set the other TransportConfig fields."""
    unique = {"namespace": f"{prefix}{uuid.uuid4().hex[:10]}",
              "rendezvous": f"tcp/127.0.0.1:{free_port()}"}  # fmt: skip
    return TransportConfig(**{**unique, **fields})  # type: ignore[arg-type]


def transport_flags(transport: TransportConfig) -> list[str]:
    """Flags that put a child process on `transport`: its namespace and every transport
    option that differs from the default (the TLS identity is each process's own)."""
    return flags({"namespace": transport.namespace, **forwarded(CommonConfig(transport=transport))})


def spawn(
    args: Sequence[str],
    transport: TransportConfig | None = None,
    log: Path | None = None,
    prefix: Sequence[str] = (),
    script: Path | None = None,
) -> subprocess.Popen:
    """`python -m hamnet <args>` (or `python <script> <args>`) on `transport`, behind the
    command `prefix` (e.g. `nice`); its output goes to `log`, or is discarded."""
    program = [str(script)] if script is not None else ["-m", "hamnet"]
    network = transport_flags(transport) if transport is not None else []
    output = log.open("w") if log is not None else subprocess.DEVNULL
    return subprocess.Popen([*prefix, sys.executable, *program, *args, *network],
                            stdout=output, stderr=subprocess.STDOUT)  # fmt: skip


def stop(processes: Sequence[subprocess.Popen], timeout: float = 30.0) -> None:
    """Terminate `processes`, wait for them, and kill those not gone within `timeout` s."""
    for process in processes:
        if process.poll() is None:
            process.terminate()
    for process in processes:
        try:
            process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
