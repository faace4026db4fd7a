"""Raw zenoh-python echo, the baseline process of `benchmarks/transport.py`.

Consumes bytes on `--key-in` and republishes each payload unchanged (and its attachment,
which carries the benchmark's sequence number) on `--key-out`, through a plain Zenoh
session configured by the runtime's `zenoh_config`, so that only the HAMnet layer (contract,
protobuf, tensor checks) differs from `hamnet echo --reflect`.

It is built like `hamnet echo`: the Zenoh callback only appends the sample to a bounded
queue under a condition variable (as `hamnet.runtime.pubsub.Inbox._push` does), and the
main thread pops it, copies the payload out of Zenoh with `ZBytes.to_bytes()` (as
`Inbox.get` does before decoding) and publishes those bytes. It tunes the allocator as every
`hamnet` process does (`keep_large_buffers`), so that this, too, is the same on both paths.
"""

from __future__ import annotations

import argparse
import signal
import threading
from collections import deque
from collections.abc import Sequence
from types import FrameType

import zenoh

from hamnet.runtime.allocator import keep_large_buffers
from hamnet.runtime.transport import TransportConfig, zenoh_config


def parse(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command-line options of the raw echo."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--key-in", required=True, help="key to consume")
    parser.add_argument("--key-out", required=True, help="key to republish on")
    parser.add_argument("--alive", required=True, help="liveliness token declared when ready")
    parser.add_argument("--namespace", required=True)
    parser.add_argument("--rendezvous", required=True, help="e.g. tcp/127.0.0.1:7460")
    parser.add_argument("--shared-memory", action=argparse.BooleanOptionalAction, default=True)
    parser.add_argument("--shm-pool-mb", type=int, default=64)
    parser.add_argument("--shm-threshold", type=int, default=3072)
    parser.add_argument("--capacity", type=int, default=1024, help="queue bound, as Inbox")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Echo until SIGINT/SIGTERM; returns the exit status."""
    args = parse(argv)
    keep_large_buffers()
    transport = TransportConfig(
        namespace=args.namespace,
        rendezvous=args.rendezvous,
        shared_memory=args.shared_memory,
        shm_pool_mb=args.shm_pool_mb,
        shm_threshold=args.shm_threshold,
    )
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)

    queue: deque[tuple[zenoh.ZBytes, zenoh.ZBytes | None]] = deque(maxlen=args.capacity)
    ready = threading.Condition()

    def push(sample: zenoh.Sample) -> None:
        with ready:
            queue.append((sample.payload, sample.attachment))
            ready.notify()

    session = zenoh.open(zenoh_config(transport))
    try:
        subscriber = session.declare_subscriber(args.key_in, push)
        publisher = session.declare_publisher(args.key_out)
        token = session.liveliness().declare_token(args.alive)
        while not stop.is_set():
            with ready:
                if not queue:
                    ready.wait(0.1)
                    continue
                payload, attachment = queue.popleft()
            publisher.put(payload.to_bytes(), attachment=attachment)
        token.undeclare()
        subscriber.undeclare()
        publisher.undeclare()
    finally:
        session.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
