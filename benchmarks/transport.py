"""Transport benchmark: round-trip latency and throughput of the HAMnet runtime beside raw Zenoh.

Consumes nothing: it opens its own Zenoh session on a fresh namespace and free loopback port
and starts two echo processes. Produces a progress line per measurement on stderr, two tables
on stdout (in-process core steps, then round trips) and, as the last stdout line, one JSON
object. It answers the transport issue's two questions: does the runtime stay within 20% of
raw Zenoh at 400 KB (`overhead_vs_raw_400k` = runtime / raw round-trip median - 1, shared
memory on as shipped), and does shared memory beat the network path at 4 MB
(`shm_speedup_4m` = runtime round-trip median with shared memory off / on;
`shm_speedup_4m_raw` is the same for raw Zenoh).

The two paths, measured in the same run and interleaved round by round:

- runtime: this process publishes a `PerceptionTokens` whose environment_cloud is (B, P, 3)
  float32 with `pubsub.Publisher`; the product's `hamnet echo --reflect` decodes it through the
  contract (tensor and finiteness checks) and republishes it unchanged; this process gets it
  back through `pubsub.Inbox` and, as a service shell would, parses it and views the cloud
  with `tensor.from_tensor` (dtype, shape and finiteness checked once).
- raw: the same serialized bytes through a plain zenoh publisher and subscriber, echoed
  unchanged by `benchmarks/raw_echo.py`.

All three processes build their session with `transport.zenoh_config`, so only the runtime
layer differs. Both paths also hand received samples over the same way: the Zenoh callback
appends the sample to a deque under a condition variable, and a Python thread pops it and
copies the payload out of Zenoh with `ZBytes.to_bytes()` (that is `Inbox` in the runtime path;
`RawEnd` here and `raw_echo.py` mirror it). So the gap between the paths is the runtime's own
work: contract lookup, protobuf encode/decode, tensor and finiteness checks.

Latency is ping-pong with one message in flight; `send`, `recv` and `remote` split the round
trip into this side's publish, this side's Zenoh delivery -> usable payload (hand-off, copy,
decode) and the rest (wire and echo process). Throughput streams with `window` messages in
flight: msg/s is echoes back per second, MB/s is payload bytes of those echoes (one way).
Before the networked runs, `transport_core.py` times the same work in-process.

    .venv/bin/python benchmarks/transport.py --quick     # < 1 min on 2 cores
    .venv/bin/python benchmarks/transport.py             # full sweep
"""

from __future__ import annotations

import gc
import os
import platform
import subprocess
import threading
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np
import tyro
import zenoh

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares, and
# the core half by name.
from common import (
    header,
    loopback_transport,
    print_header,
    progress,
    report,
    spawn,
    stop,
)
from transport_core import (
    BENCH_WORKER,
    ECHO_WORKER,
    SHAPES,
    TOKENS,
    core_profile,
    decode_reply,
    make_message,
    stats_us,
)

from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.runtime.allocator import keep_large_buffers
from hamnet.runtime.codec import encode
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import from_tensor
from hamnet.runtime.transport import TransportConfig, open_session
from hamnet.tools.echo import reflect_key

RAW_ECHO = Path(__file__).with_name("raw_echo.py")
PATHS = ("runtime", "raw")


@dataclass(frozen=True)
class SizePlan:
    """How much to measure at one payload size (full mode; --quick divides)."""

    round_trips: int
    """Ping-pong round trips per path and shared-memory setting."""
    stream: int
    """Messages per path streamed with `window` in flight, for throughput."""
    core: int
    """Repetitions of each in-process codec measurement."""


PLANS: dict[str, SizePlan] = {
    "1k": SizePlan(round_trips=5000, stream=10000, core=2000),
    "400k": SizePlan(round_trips=2000, stream=3000, core=400),
    "4m": SizePlan(round_trips=400, stream=400, core=40),
}


@dataclass(frozen=True)
class TransportBenchConfig:
    """Round-trip latency and throughput of the runtime beside raw Zenoh."""

    quick: bool = False
    """Fewer iterations (finishes within a minute on a 2-core machine)."""
    sizes: tuple[str, ...] = ("1k", "400k", "4m")
    """Payload sizes to sweep: 1k, 400k, 4m."""
    seed: int = 0
    """Seed of the point clouds."""
    window: int = 4
    """Messages in flight while streaming for throughput."""
    shm_pool_mb: int = 64
    """Shared-memory pool of every process, MiB."""
    shm_threshold: int = 3072
    """Payload bytes from which shared memory is used (the runtime's default)."""
    timeout_s: float = 2.0
    """An echo not back within this many seconds counts as lost."""

    def __post_init__(self) -> None:
        unknown = set(self.sizes) - set(SHAPES)
        if unknown or not self.sizes:
            raise ValueError(f"sizes must be among {sorted(SHAPES)}, got {self.sizes}")
        if self.window < 1 or self.timeout_s <= 0:
            raise ValueError("window must be >= 1 and timeout_s > 0")

    @property
    def rounds(self) -> int:
        """Alternating runtime/raw blocks per size, so that drift hits both paths alike."""
        return 2 if self.quick else 5

    def plan(self, size: str) -> SizePlan:
        """Iterations at `size` for this mode."""
        full = PLANS[size]
        if not self.quick:
            return full
        return SizePlan(
            round_trips=full.round_trips // 3,
            stream=full.stream // 3,
            core=max(full.core // 3, 10),
        )


# ---------------------------------------------------------------------------------------------
# The two ends this process holds: send a ping, receive its echo as an array or as bytes.


class RuntimeEnd:
    """The benchmark's end of the runtime path: `Publisher` out, `Inbox` back, numpy view."""

    name = "runtime"

    def __init__(self, session: zenoh.Session, namespace: str) -> None:
        self.session = session
        self.ping_key = TOKENS.key(namespace, w=BENCH_WORKER)
        self.reply_key = reflect_key(namespace, ECHO_WORKER, self.ping_key)
        self.drops = DropCounter()
        self.inbox = Inbox(session, self.drops)
        self.inbox.subscribe("reflect", self.reply_key, decoder=decode_reply)
        self.publisher = Publisher(session, self.ping_key, f"bench/{BENCH_WORKER}")
        self.message = PerceptionTokens()
        self.payload_bytes = 0
        self.last: np.ndarray | None = None

    def load(self, message: PerceptionTokens) -> None:
        """Send `message` (its header.step set to the sequence number) from now on."""
        self.message = message
        self.payload_bytes = message.ByteSize()

    def send(self, seq: int) -> None:
        self.message.header.step = seq
        self.publisher.put(self.message)

    def receive(self, timeout: float) -> tuple[int, int] | None:
        """(sequence number, Zenoh delivery time in monotonic ns) of the next echo, or None."""
        received = self.inbox.get(timeout)
        if received is None:
            return None
        step, self.last = received.value
        return step, received.received_ns

    def echoed_intact(self) -> bool:
        """Whether the last echo carried the cloud that was sent."""
        sent = from_tensor(self.message.environment_cloud)
        return self.last is not None and np.array_equal(self.last, sent)

    def close(self) -> None:
        self.inbox.close()
        self.publisher.close()


class RawEnd:
    """The benchmark's end of the raw path: plain zenoh publisher and subscriber of bytes.

    `_push` and `receive` mirror `Inbox._push` and `Inbox.get` (deque and condition variable,
    then `to_bytes()` on this thread); the sequence number rides in an 8-byte attachment
    because the payload is opaque here.
    """

    name = "raw"

    def __init__(self, session: zenoh.Session, namespace: str) -> None:
        self.session = session
        self.ping_key = f"hamnet/{namespace}/bench/raw/ping"
        self.reply_key = f"hamnet/{namespace}/bench/raw/pong"
        self._queue: deque[tuple[zenoh.ZBytes, zenoh.ZBytes | None, int]] = deque(maxlen=1024)
        self._ready = threading.Condition()
        self._subscriber = session.declare_subscriber(self.reply_key, self._push)
        self._publisher = session.declare_publisher(self.ping_key)
        self.payload = b""
        self.payload_bytes = 0
        self.last = b""

    def _push(self, sample: zenoh.Sample) -> None:
        item = (sample.payload, sample.attachment, time.monotonic_ns())
        with self._ready:
            self._queue.append(item)
            self._ready.notify()

    def load(self, message: PerceptionTokens) -> None:
        """Send the serialized `message` from now on (same bytes as the runtime path)."""
        self.payload = encode(message)
        self.payload_bytes = len(self.payload)

    def send(self, seq: int) -> None:
        self._publisher.put(self.payload, attachment=seq.to_bytes(8, "little"))

    def receive(self, timeout: float) -> tuple[int, int] | None:
        deadline = time.monotonic() + timeout
        with self._ready:
            while not self._queue:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._ready.wait(remaining)
            payload, attachment, stamp = self._queue.popleft()
        self.last = payload.to_bytes()
        seq = int.from_bytes(attachment.to_bytes(), "little") if attachment is not None else -1
        return seq, stamp

    def echoed_intact(self) -> bool:
        return self.last == self.payload

    def close(self) -> None:
        self._subscriber.undeclare()
        self._publisher.undeclare()


End = RuntimeEnd | RawEnd


@dataclass
class Measurement:
    """Everything measured for one (shared memory, path, size)."""

    round_trip_ns: list[int] = field(default_factory=list)
    send_ns: list[int] = field(default_factory=list)
    """Start -> put returned (encode and hand-over to Zenoh)."""
    receive_ns: list[int] = field(default_factory=list)
    """Zenoh delivery on this side -> payload usable (hand-off, copy, decode)."""
    stream_s: float = 0.0
    streamed: int = 0
    lost: int = 0
    via_shm: float = float("nan")
    """Share of echoes, sampled after the measurement, that arrived in shared memory."""


class Sequencer:
    """Sequence numbers unique over the whole run, so a late echo never passes for a new one."""

    def __init__(self) -> None:
        self.next = 1

    def __call__(self) -> int:
        self.next += 1
        return self.next - 1


def await_echo(end: End, seq: int, timeout: float) -> tuple[int, int] | None:
    """The echo of `seq` (skipping stale ones), or None after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while (remaining := deadline - time.monotonic()) > 0:
        reply = end.receive(remaining)
        if reply is not None and reply[0] == seq:
            return reply
    return None


def ping_pong(end: End, sequence: Sequencer, count: int, timeout: float, into: Measurement) -> None:
    """`count` round trips, one message in flight."""
    gc.collect()
    for _ in range(count):
        seq = sequence()
        start = time.monotonic_ns()
        end.send(seq)
        sent = time.monotonic_ns()
        reply = await_echo(end, seq, timeout)
        done = time.monotonic_ns()
        if reply is None:
            into.lost += 1
            continue
        into.round_trip_ns.append(done - start)
        into.send_ns.append(sent - start)
        into.receive_ns.append(done - reply[1])


def stream(
    end: End, sequence: Sequencer, count: int, window: int, timeout: float, into: Measurement
) -> None:
    """Send `count` messages keeping `window` in flight; time until the last echo is back.

    When no echo comes within `timeout`, what is in flight counts as lost and the wait is
    left out of the time, so one loss does not pass for a slow stream.
    """
    gc.collect()
    waiting: set[int] = set()
    sent = 0
    stalled = 0.0
    start = time.monotonic()
    while sent < count or waiting:
        while sent < count and len(waiting) < window:
            seq = sequence()
            end.send(seq)
            waiting.add(seq)
            sent += 1
        wait_start = time.monotonic()
        reply = end.receive(timeout)
        if reply is None:
            stalled += time.monotonic() - wait_start
            into.lost += len(waiting)
            waiting.clear()
        elif reply[0] in waiting:
            waiting.discard(reply[0])
            into.streamed += 1
    into.stream_s += time.monotonic() - start - stalled


def shm_share(
    end: End, sequence: Sequencer, count: int, timeout: float, until_seen: float = 0.0
) -> float:
    """Share of `count` echoes that arrive in shared memory (`ZBytes.as_shm()`).

    A second subscriber on the echo key looks at each sample, so neither path pays for the
    probe while it is measured. With `until_seen` > 0, first ping for up to that many seconds
    until one echo arrives in shared memory: Zenoh creates its pool lazily, in every process,
    on the first large message, and the first echoes go over the network meanwhile.
    """
    seen: list[bool] = []
    probe = end.session.declare_subscriber(
        end.reply_key, lambda sample: seen.append(sample.payload.as_shm() is not None)
    )
    try:
        deadline = time.monotonic() + until_seen
        while time.monotonic() < deadline and not any(seen):
            ping_pong(end, sequence, 1, timeout, Measurement())
        seen.clear()
        ping_pong(end, sequence, count, timeout, Measurement())
        return float(np.mean(seen)) if seen else float("nan")
    finally:
        probe.undeclare()


def warm_up(
    end: End, sequence: Sequencer, config: TransportBenchConfig, size: str, shm: bool
) -> None:
    """Ping until the first echo (subscriptions may still be propagating), check it, warm up.

    With shared memory on and a payload above the threshold, also wait for the pools.
    """
    deadline = time.monotonic() + 20.0
    while True:
        seq = sequence()
        end.send(seq)
        if await_echo(end, seq, 0.5) is not None:
            break
        if time.monotonic() > deadline:
            raise RuntimeError(f"no echo on the {end.name} path within 20 s")
    if not end.echoed_intact():
        raise RuntimeError(f"the {end.name} echo changed the payload at {size}")
    if shm and end.payload_bytes >= config.shm_threshold:
        shm_share(end, sequence, 1, config.timeout_s, until_seen=10.0)
    scratch = Measurement()
    ping_pong(end, sequence, max(config.plan(size).round_trips // 10, 5), config.timeout_s, scratch)
    stream(end, sequence, config.window * 2, config.window, config.timeout_s, scratch)


# ---------------------------------------------------------------------------------------------
# Processes: this session holds the rendezvous; the two echoes connect to it.


def start_echoes(
    transport: TransportConfig, runtime: RuntimeEnd, raw: RawEnd
) -> list[subprocess.Popen]:
    """Start `hamnet echo --reflect` and the raw echo on `transport`'s namespace and rendezvous."""
    hamnet_echo = ["echo", "--reflect", "--worker", ECHO_WORKER, "--key-expr", runtime.ping_key,
                   "--log-level", "warning"]  # fmt: skip
    raw_echo = ["--key-in", raw.ping_key, "--key-out", raw.reply_key,
                "--alive", f"hamnet/{transport.namespace}/alive/raw-echo/0"]  # fmt: skip
    return [spawn(hamnet_echo, transport), spawn(raw_echo, transport, script=RAW_ECHO)]


def await_alive(session: zenoh.Session, namespace: str, children: list[subprocess.Popen]) -> None:
    """Wait for both echoes' liveliness tokens (raise if one exits or 30 s pass)."""
    alive = f"hamnet/{namespace}/alive"
    wanted = {f"{alive}/echo/{ECHO_WORKER}", f"{alive}/raw-echo/0"}
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        for child in children:
            if child.poll() is not None:
                raise RuntimeError(f"{child.args[1:4]} exited with status {child.returncode}")
        seen = {
            str(reply.ok.key_expr)
            for reply in session.liveliness().get(f"{alive}/**", timeout=1.0)
            if reply.ok is not None
        }
        if wanted <= seen:
            return
        time.sleep(0.1)
    raise RuntimeError(f"echo processes not alive after 30 s (missing {sorted(wanted - seen)})")


@contextmanager
def echo_stack(
    config: TransportBenchConfig, shared_memory: bool
) -> Iterator[tuple[RuntimeEnd, RawEnd]]:
    """This process's session and both echo processes, all with `shared_memory` on or off."""
    transport = loopback_transport(
        shared_memory=shared_memory,
        shm_pool_mb=config.shm_pool_mb,
        shm_threshold=config.shm_threshold,
    )
    session = open_session(transport)  # first, so it holds the rendezvous
    children: list[subprocess.Popen] = []
    ends: list[End] = []
    try:
        ends = [RuntimeEnd(session, transport.namespace), RawEnd(session, transport.namespace)]
        children = start_echoes(transport, *ends)
        await_alive(session, transport.namespace, children)
        yield ends[0], ends[1]
    finally:
        stop(children, timeout=5.0)
        for end in ends:
            end.close()
        session.close()


def measure_shm_setting(
    config: TransportBenchConfig, shared_memory: bool, messages: dict[str, PerceptionTokens]
) -> dict[str, dict[str, Measurement]]:
    """Every size on both paths, with shared memory on or off in all three processes."""
    results: dict[str, dict[str, Measurement]] = {path: {} for path in PATHS}
    sequence = Sequencer()
    label = "shm on " if shared_memory else "shm off"
    with echo_stack(config, shared_memory) as ends:
        for size in config.sizes:
            plan = config.plan(size)
            for end in ends:
                end.load(messages[size])
                warm_up(end, sequence, config, size, shared_memory)
            measured = {end.name: Measurement() for end in ends}
            round_trips, streamed = plan.round_trips // config.rounds, plan.stream // config.rounds
            for round_ in range(config.rounds):
                for end in ends if round_ % 2 == 0 else ends[::-1]:
                    into = measured[end.name]
                    ping_pong(end, sequence, round_trips, config.timeout_s, into)
                    stream(end, sequence, streamed, config.window, config.timeout_s, into)
            for end in ends:
                measurement = measured[end.name]
                measurement.via_shm = shm_share(end, sequence, 10, config.timeout_s)
                results[end.name][size] = measurement
                figures = summarize(measurement, messages[size].ByteSize())
                progress(
                    f"[transport] {label} {size:>4} {end.name:<7} round trip median "
                    f"{figures['round_trip_median_us'] / 1e3:7.3f} ms "
                    f"p99 {figures['round_trip_p99_us'] / 1e3:7.3f} ms "
                    f"(n={figures['round_trips']}) | {figures['throughput_msg_s']:8.1f} msg/s "
                    f"{figures['throughput_mb_s']:7.1f} MB/s | lost {measurement.lost} | "
                    f"via shm {measurement.via_shm:.0%}"
                )
    return results


# ---------------------------------------------------------------------------------------------
# Report.


def summarize(measurement: Measurement, payload_bytes: int) -> dict[str, float]:
    """JSON figures of one measurement; `remote` is the round trip less this side's work."""
    rate = measurement.streamed / max(measurement.stream_s, 1e-9)
    round_trip = stats_us(measurement.round_trip_ns)
    remote = np.subtract(
        np.subtract(measurement.round_trip_ns, measurement.send_ns), measurement.receive_ns
    )
    return {
        "round_trip_median_us": round_trip["median_us"],
        "round_trip_p99_us": round_trip["p99_us"],
        "round_trips": round_trip["n"],
        "send_median_us": stats_us(measurement.send_ns)["median_us"],
        "remote_median_us": stats_us(remote)["median_us"],
        "receive_median_us": stats_us(measurement.receive_ns)["median_us"],
        "throughput_msg_s": round(rate, 1),
        "throughput_mb_s": round(rate * payload_bytes / 1e6, 1),
        "streamed": measurement.streamed,
        "lost": measurement.lost,
        "via_shm": round(measurement.via_shm, 2),
    }


def ratio(numerator: float, denominator: float) -> float:
    """numerator / denominator, NaN when undefined."""
    return round(numerator / denominator, 3) if denominator > 0 else float("nan")


def print_profile(profile: dict[str, dict[str, dict[str, float]]]) -> None:
    """Median of each in-process step per size, microseconds."""
    sizes = list(profile)
    print("core, in-process, median us " + "".join(f"{size:>10}" for size in sizes))
    for step in profile[sizes[0]]:
        cells = "".join(f"{profile[size][step]['median_us']:>10.1f}" for size in sizes)
        print(f"  {step:<30}{cells}")
    print()


def print_table(results: dict, sizes: tuple[str, ...], payload: dict[str, int]) -> None:
    """Every measurement, runtime beside raw; times in ms (send/remote/recv split the median)."""
    print_header(
        f"{'size':>5} {'bytes':>9} {'shm':>4} {'path':<8} {'rt median':>9} {'rt p99':>8} "
        f"{'send':>7} {'remote':>7} {'recv':>7} {'msg/s':>8} {'MB/s':>7} {'lost':>4} "
        f"{'via shm':>7} {'vs raw':>6}"
    )
    for size in sizes:
        for shm in ("on", "off"):
            raw_median = results[f"shm_{shm}"]["raw"][size]["round_trip_median_us"]
            for path in PATHS:
                row = results[f"shm_{shm}"][path][size]
                overhead = row["round_trip_median_us"] / raw_median - 1
                versus = "" if path == "raw" else f"{overhead:+.0%}"
                print(
                    f"{size:>5} {payload[size]:>9} {shm:>4} {path:<8} "
                    f"{row['round_trip_median_us'] / 1e3:>9.3f} "
                    f"{row['round_trip_p99_us'] / 1e3:>8.3f} "
                    f"{row['send_median_us'] / 1e3:>7.3f} {row['remote_median_us'] / 1e3:>7.3f} "
                    f"{row['receive_median_us'] / 1e3:>7.3f} {row['throughput_msg_s']:>8.1f} "
                    f"{row['throughput_mb_s']:>7.1f} {row['lost']:>4} "
                    f"{row['via_shm']:>7.0%} {versus:>6}"
                )
        print()


def without_nan(value: object) -> object:
    """`value` with NaN floats replaced by None, so the JSON line is strict JSON."""
    if isinstance(value, dict):
        return {key: without_nan(item) for key, item in value.items()}
    if isinstance(value, float) and value != value:
        return None
    return value


def main(config: TransportBenchConfig) -> dict:
    """Run the benchmark; returns the JSON figures."""
    started = time.monotonic()
    messages = {size: make_message(SHAPES[size], config.seed) for size in config.sizes}
    payload = {size: message.ByteSize() for size, message in messages.items()}

    profile = {}
    for size in config.sizes:
        profile[size] = core_profile(messages[size], config.plan(size).core)
        steps = ", ".join(f"{k} {v['median_us']:.1f}" for k, v in profile[size].items())
        progress(f"[transport] core {size} (median us): {steps}")

    results: dict[str, dict[str, dict[str, dict[str, float]]]] = {}
    for shared_memory in (True, False):
        measured = measure_shm_setting(config, shared_memory, messages)
        results["shm_on" if shared_memory else "shm_off"] = {
            path: {size: summarize(m, payload[size]) for size, m in by_size.items()}
            for path, by_size in measured.items()
        }

    print_profile(profile)
    print_table(results, config.sizes, payload)

    def median(shm: str, path: str, size: str) -> float:
        row = results[shm][path].get(size)
        return row["round_trip_median_us"] if row else float("nan")

    overhead = {
        f"{shm}_{size}": round(ratio(median(shm, "runtime", size), median(shm, "raw", size)) - 1, 3)
        for shm in results
        for size in config.sizes
    }
    figures = {
        **header("transport", config.quick),
        "overhead_vs_raw_400k": overhead.get("shm_on_400k", float("nan")),
        "shm_speedup_4m": ratio(
            median("shm_off", "runtime", "4m"), median("shm_on", "runtime", "4m")
        ),
        "shm_speedup_4m_raw": ratio(median("shm_off", "raw", "4m"), median("shm_on", "raw", "4m")),
        "overhead_vs_raw": overhead,
        "payload_bytes": payload,
        "results": results,
        "core_median_us": {
            size: {step: v["median_us"] for step, v in steps.items()}
            for size, steps in profile.items()
        },
        "seed": config.seed,
        "window": config.window,
        "rounds": config.rounds,
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "zenoh": metadata.version("eclipse-zenoh"),
        "protobuf": metadata.version("protobuf"),
        "glibc_tunables": os.environ.get("GLIBC_TUNABLES", ""),
        "elapsed_s": round(time.monotonic() - started, 1),
    }
    figures["goals"] = {
        "runtime_overhead_under_20pct_at_400k": figures["overhead_vs_raw_400k"] < 0.20,
        "shm_beats_network_at_4m": figures["shm_speedup_4m"] > 1.0,
    }
    return without_nan(figures)


if __name__ == "__main__":
    keep_large_buffers()  # as every `hamnet` process and raw_echo.py do
    report(main(tyro.cli(TransportBenchConfig, description=__doc__)))
