"""The runtime's per-message work, timed in-process without Zenoh: the core half of
`benchmarks/transport.py`, which imports it.

Consumes nothing; produces, per payload size, the median and p99 of each step the runtime adds
to a message (encode, parse, tensor checks, finiteness, contract lookup, numpy view, inbox
hand-off) and of the Python work of each hop of both benchmark paths, so that the networked
gap between the runtime and raw Zenoh can be broken down.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from types import SimpleNamespace

import numpy as np
import zenoh

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import durations, summary

from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.runtime import contract
from hamnet.runtime.codec import decode, encode, iter_tensors, parse
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import all_finite, from_tensor, to_tensor
from hamnet.tools.echo import decode_by_contract, reflect_key

TOKENS = contract.topic("perception/<w>/tokens")
"""The topic both paths carry: PerceptionTokens, finite floats required."""
ECHO_WORKER = "0"
BENCH_WORKER = "bench"

SHAPES: dict[str, tuple[int, int, int]] = {
    "1k": (1, 85, 3),  # 1,020 B of points: one small cloud
    "400k": (64, 512, 3),  # 393,216 B: 64 environments x one 512-point cloud
    "4m": (64, 5461, 3),  # 4,193,856 B: 64 environments x 5,461 points
}
"""environment_cloud shape (B, P, 3) float32 per payload size."""


def make_message(shape: tuple[int, int, int], seed: int) -> PerceptionTokens:
    """A PerceptionTokens whose environment_cloud is a random (B, P, 3) float32 cloud, m."""
    cloud = np.random.default_rng(seed).standard_normal(shape, dtype=np.float32)  # (B, P, 3)
    message = PerceptionTokens()
    # Header as the Publisher fills it, so the raw path carries exactly the same bytes.
    message.header.source = f"bench/{BENCH_WORKER}"
    message.header.stamp_ns = time.time_ns()
    message.header.step = 1 << 20  # sequence numbers of a long run
    to_tensor(cloud, message.environment_cloud)
    return message


def stats_us(samples: list[int] | np.ndarray, scale: float = 1e-3) -> dict[str, float]:
    """Median and p99 of `samples` times `scale` (default: nanoseconds) in microseconds, and
    their count; NaN when there are none (every echo lost)."""
    if len(samples) == 0:
        return {"median_us": float("nan"), "p99_us": float("nan"), "n": 0}
    return {**summary(samples, "us", scale, digits=1), "n": len(samples)}


class _LoopbackSession:
    """Just enough of a zenoh.Session for the runtime's Inbox and Publisher, without Zenoh.

    A publisher's put does nothing; a subscriber's callback is kept for the caller to call.
    """

    def declare_subscriber(
        self, key_expr: str, callback: Callable, allowed_origin: zenoh.Locality | None = None
    ) -> SimpleNamespace:
        self.callback = callback
        return SimpleNamespace(undeclare=lambda: None)

    def declare_publisher(
        self, key_expr: str, congestion_control: zenoh.CongestionControl | None = None
    ) -> SimpleNamespace:
        return SimpleNamespace(put=lambda payload: None, undeclare=lambda: None)


def handoff_ns(repetitions: int) -> list[int]:
    """Inbox hand-off: a callback on another thread pushes, the blocked `get` wakes up.

    The pushing thread waits for the consumer to block again before each push, as in a
    ping-pong; the payload is one byte, so this is the wake-up, not the copy.
    """
    session = _LoopbackSession()
    inbox = Inbox(session, DropCounter())  # type: ignore[arg-type]
    inbox.subscribe("handoff", "k", decoder=lambda key, payload: payload)
    sample = SimpleNamespace(key_expr="k", payload=zenoh.ZBytes(b"x"))
    consumed = threading.Event()

    def producer() -> None:
        for _ in range(repetitions + 2):
            time.sleep(0.0005)  # let the consumer block in get()
            consumed.clear()
            session.callback(sample)
            consumed.wait()

    thread = threading.Thread(target=producer, daemon=True)
    thread.start()
    samples = []
    for _ in range(repetitions + 2):
        received = inbox.get(timeout=5.0)
        samples.append(time.monotonic_ns() - received.received_ns)
        consumed.set()
    thread.join()
    return samples[2:]


def decode_reply(key: str, payload: bytes) -> tuple[int, np.ndarray]:
    """What a service shell does with the tokens it uses: parse, then view and check the
    cloud once (dtype, shape, finiteness). Returns (header step, cloud (B, P, 3))."""
    message = parse(PerceptionTokens, payload)
    cloud = from_tensor(message.environment_cloud, np.float32, (None, None, 3), TOKENS.finite)
    return message.header.step, cloud


def core_steps(message: PerceptionTokens) -> dict[str, Callable[[], object]]:
    """Each step the runtime adds per message, and the Python work of each hop of both paths.

    The hops replay what each process does between Zenoh calls, with the product's own
    functions and Zenoh's put replaced by a no-op: `runtime_echo` is the body of
    `hamnet echo --reflect`'s loop, `raw_echo` that of `raw_echo.py`; the raw path's send
    is a bare put, so it has no Python work here.
    """
    payload = encode(message)
    parsed = PerceptionTokens.FromString(payload)
    cloud = from_tensor(parsed.environment_cloud)  # (B, P, 3)
    zbytes = zenoh.ZBytes(payload)
    namespace = "bench"
    key = TOKENS.key(namespace, w=BENCH_WORKER)
    session = _LoopbackSession()
    bench_publisher = Publisher(session, key, f"bench/{BENCH_WORKER}")  # type: ignore[arg-type]
    echo_publishers: dict[str, Publisher] = {}

    def tensor_checks() -> None:
        for _, tensor in iter_tensors(parsed):
            from_tensor(tensor, finite=False)

    def runtime_echo() -> None:  # services/tools/echo.py, per message
        _, payload = decode_by_contract(key, zbytes.to_bytes())
        reflected = reflect_key(namespace, ECHO_WORKER, key)
        if reflected not in echo_publishers:  # Service.publisher
            echo_publishers[reflected] = Publisher(session, reflected, "echo/0")  # type: ignore
        echo_publishers[reflected].put_encoded(payload)

    def runtime_receive() -> None:  # transport.RuntimeEnd.receive after the hand-off
        decode_reply(key, zbytes.to_bytes())

    return {
        "encode": lambda: encode(message),
        "copy_out": zbytes.to_bytes,
        "parse": lambda: PerceptionTokens.FromString(payload),
        "tensor_data": lambda: parsed.environment_cloud.data,
        "tensor_checks": tensor_checks,
        "finite": lambda: all_finite(cloud),
        "decode": lambda: decode(PerceptionTokens, payload, finite=True),
        "contract_match": lambda: contract.match_key(key),
        "from_tensor": lambda: from_tensor(parsed.environment_cloud, np.float32, (None, None, 3)),
        "to_tensor": lambda: to_tensor(cloud, PerceptionTokens().environment_cloud),
        "runtime_send": lambda: bench_publisher.put(message),
        "runtime_echo": runtime_echo,
        "runtime_receive": runtime_receive,
        "raw_echo": zbytes.to_bytes,
        "raw_receive": zbytes.to_bytes,
    }


def core_profile(message: PerceptionTokens, repetitions: int) -> dict[str, dict[str, float]]:
    """Median/p99 (us) of each step for `message`, and the runtime's extra work per round trip.

    Steps: `encode` (SerializeToString), `copy_out` (ZBytes.to_bytes, paid by both paths),
    `parse` (ParseFromString), `tensor_data` (one read of Tensor.data, which copies),
    `tensor_checks` (dtype and byte count of every tensor), `finite` (NaN/Inf check),
    `decode` (codec.decode: the three before), `contract_match` (key -> topic in the echo),
    `from_tensor` (the receiver's numpy view), `to_tensor` (the producer's array -> message,
    outside the round trip), `handoff` (Inbox callback -> woken `get`, paid by both paths).
    Per round trip the runtime encodes once, decodes twice and builds one numpy view.
    """
    steps = core_steps(message)
    profile = {
        name: stats_us(durations(step, repetitions, warmup=2), scale=1e6)
        for name, step in steps.items()
    }
    profile["handoff"] = stats_us(handoff_ns(min(repetitions, 200)))
    runtime = sum(profile[f"runtime_{hop}"]["median_us"] for hop in ("send", "echo", "receive"))
    raw = sum(profile[f"raw_{hop}"]["median_us"] for hop in ("echo", "receive"))
    profile["runtime_extra_per_round_trip"] = {"median_us": round(runtime - raw, 1)}
    return profile
