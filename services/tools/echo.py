"""`hamnet echo`: decode everything published on a stack through the contract, print rates
(or each message), and optionally reflect each valid message back.

Reflection republishes a message received on `hamnet/<ns>/<path>` to
`hamnet/<ns>/echo/<w>/reflect/<path>` once it has decoded and passed every check, unchanged,
as a relay should: a round trip through a second process that the contract tests and the
transport benchmark rely on.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

from google.protobuf import text_format
from google.protobuf.message import Message

from hamnet.runtime import keys
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.codec import decode
from hamnet.runtime.contract import match_key
from hamnet.runtime.service import Service

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class EchoConfig:
    """Print, count or reflect what is published on the stack."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    key_expr: str = ""
    """Key expression to listen to; empty means every key of the namespace."""
    print_messages: bool = False
    """Print each message (tensors summarised) instead of periodic rate lines."""
    reflect: bool = False
    """Republish each valid message unchanged under hamnet/<ns>/echo/<worker>/reflect/<path>."""
    period_s: float = 2.0
    """Seconds between rate lines."""
    count: int = 0
    """Exit after this many valid messages (0: run until stopped)."""
    duration_s: float = 0.0
    """Exit after this many seconds (0: run until stopped)."""


def reflect_key(namespace: str, worker: str, key: str) -> str:
    """Where a message received on `key` is reflected."""
    path = key.split("/", 2)[2]
    return f"{keys.ROOT}/{namespace}/echo/{worker}/reflect/{path}"


def decode_by_contract(key: str, payload: bytes) -> tuple[Message | None, bytes]:
    """Decode a payload with the message type the contract gives its key.

    Returns:
        The message (None for keys outside the contract) and the payload it came from.
    """
    topic = match_key(key)
    if topic is None or topic.message is None:
        return None, payload
    return decode(topic.message, payload, topic.finite), payload


def summary(message: Message, limit: int = 400) -> str:
    """One-line text of a message, bytes fields abbreviated."""
    text = text_format.MessageToString(
        message, as_one_line=True, use_short_repeated_primitives=True
    )
    return text if len(text) <= limit else text[:limit] + "..."


CONFIG = EchoConfig
"""The config `hamnet echo` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet echo` with command-line arguments `argv`; returns the exit status."""
    config, identity = parse_service(CONFIG, argv, "echo", __doc__)
    common = config.common
    namespace = common.transport.namespace
    own_prefix = f"{keys.ROOT}/{namespace}/echo/"
    counts: Counter[str] = Counter()
    total = 0
    started = last_report = time.monotonic()
    with Service(identity, common.transport) as service:
        key_expr = config.key_expr or keys.namespace_pattern(namespace)
        # Remote only: its own reflections and health reports would come straight back.
        service.inbox.subscribe("stack", key_expr, decoder=decode_by_contract, remote_only=True)
        while service.running:
            now = time.monotonic()
            if config.duration_s and now - started >= config.duration_s:
                break
            if not config.print_messages and now - last_report >= config.period_s:
                elapsed = now - last_report
                rates = ", ".join(f"{k} {n / elapsed:.1f}/s" for k, n in sorted(counts.items()))
                log.info("%s", rates or "nothing received")
                counts.clear()
                last_report = now
            received = service.receive(timeout=0.1)
            # Never reflect what an echo (this one or another) published: no ping-pong.
            if received is None or received.key.startswith(own_prefix):
                continue
            message, payload = received.value
            if message is None:
                continue
            counts[received.key] += 1
            total += 1
            if config.print_messages:
                print(f"{received.key}: {summary(message)}", flush=True)
            if config.reflect:
                reflected = reflect_key(namespace, common.worker, received.key)
                service.publisher(reflected).put_encoded(payload)
            if config.count and total >= config.count:
                break
    return 0
