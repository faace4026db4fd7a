"""Typed publishers and subscribers over a Zenoh session.

Zenoh callbacks run on Zenoh's threads, so they only append the raw payload to a bounded
inbox; decoding and all real work happen on the service thread that calls `Inbox.get`.
A payload that fails to decode is counted under (topic, reason), logged once per kind, and
dropped; when the inbox is full the oldest payload is dropped and counted as `overflow`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import zenoh
from google.protobuf.message import Message

from hamnet.runtime.codec import decode, encode
from hamnet.runtime.tensor import PayloadError

log = logging.getLogger(__name__)

T = TypeVar("T")


class DropCounter:
    """Counts dropped payloads by (key, reason) and logs the first of each kind."""

    def __init__(self) -> None:
        self.counts: Counter[tuple[str, str]] = Counter()
        self._lock = threading.Lock()

    def drop(self, key: str, reason: str, detail: str) -> None:
        """Count one payload dropped on `key`; log it when its kind is new."""
        with self._lock:
            self.counts[(key, reason)] += 1
            first = self.counts[(key, reason)] == 1
        if first:
            log.warning(
                "dropped payload on %s (%s): %s; further drops of this kind are only counted",
                key,
                reason,
                detail,
            )

    @property
    def total(self) -> int:
        """All drops so far."""
        return sum(self.counts.values())


@dataclass(frozen=True)
class Received(Generic[T]):
    """One decoded message handed to the service thread."""

    name: str
    """Local name the service gave the subscription."""
    key: str
    """Concrete key the message arrived on."""
    value: T
    """The decoded value (a protobuf message, or what the subscription's decoder returned)."""
    received_ns: int
    """time.monotonic_ns() when Zenoh delivered it."""


@dataclass
class _Subscription:
    name: str
    decode: Callable[[str, bytes], Any]
    handle: Any = None
    received: int = 0


class Inbox:
    """Subscriptions that feed one bounded queue, drained by the service thread."""

    def __init__(self, session: zenoh.Session, drops: DropCounter, capacity: int = 1024) -> None:
        self._session = session
        self._drops = drops
        self._queue: deque[tuple[_Subscription, str, zenoh.ZBytes, int]] = deque()
        self._capacity = capacity
        self._ready = threading.Condition()
        self._subscriptions: list[_Subscription] = []

    def subscribe(
        self,
        name: str,
        key_expr: str,
        message_type: type[Message] | None = None,
        finite: bool = True,
        decoder: Callable[[str, bytes], Any] | None = None,
        remote_only: bool = False,
    ) -> None:
        """Receive `key_expr` under the local `name`.

        Either `message_type` (decoded and checked with `codec.decode`) or a custom
        `decoder(key, payload)` raising PayloadError for bad input. `remote_only` ignores
        what this process publishes itself (for tools that listen to everything).
        """
        if decoder is None:
            if message_type is None:
                raise ValueError("subscribe needs a message_type or a decoder")
            decoder = lambda key, payload, mt=message_type: decode(mt, payload, finite)  # noqa: E731
        subscription = _Subscription(name, decoder)
        origin = zenoh.Locality.REMOTE if remote_only else zenoh.Locality.ANY
        subscription.handle = self._session.declare_subscriber(
            key_expr, lambda sample: self._push(subscription, sample), allowed_origin=origin
        )
        self._subscriptions.append(subscription)

    def _push(self, subscription: _Subscription, sample: zenoh.Sample) -> None:
        item = (subscription, str(sample.key_expr), sample.payload, time.monotonic_ns())
        with self._ready:
            subscription.received += 1
            if len(self._queue) >= self._capacity:
                _, dropped_key, _, _ = self._queue.popleft()
                self._drops.drop(dropped_key, "overflow", f"inbox full ({self._capacity})")
            self._queue.append(item)
            self._ready.notify()

    def get(self, timeout: float | None = None) -> Received | None:
        """Next decoded message, or None if nothing valid arrived within `timeout` seconds."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            with self._ready:
                while not self._queue:
                    remaining = None if deadline is None else deadline - time.monotonic()
                    if remaining is not None and remaining <= 0:
                        return None
                    self._ready.wait(remaining)
                subscription, key, payload, stamp = self._queue.popleft()
            try:
                value = subscription.decode(key, payload.to_bytes())
            except PayloadError as error:
                self._drops.drop(key, error.reason, error.detail)
                continue
            return Received(subscription.name, key, value, stamp)

    @property
    def received(self) -> dict[str, int]:
        """Payloads delivered by Zenoh so far per subscription name (valid, bad or dropped)."""
        return {s.name: s.received for s in self._subscriptions}

    def close(self) -> None:
        """Undeclare every subscription."""
        for subscription in self._subscriptions:
            subscription.handle.undeclare()
        self._subscriptions.clear()


class Publisher:
    """Publishes protobuf messages on one key, stamping their header."""

    def __init__(self, session: zenoh.Session, key: str, source: str) -> None:
        self.key = key
        self.source = source
        self.published = 0
        self._publisher = session.declare_publisher(key)

    def put(self, message: Message) -> None:
        """Encode and publish; fills `header.source` and `header.stamp_ns` where unset.

        Set fields are kept, so a message forwarded unchanged (echo, replay) stays equal.
        """
        if "header" in message.DESCRIPTOR.fields_by_name:
            header = message.header
            header.source = header.source or self.source
            header.stamp_ns = header.stamp_ns or time.time_ns()
        self.put_encoded(encode(message))

    def put_encoded(self, payload: bytes) -> None:
        """Publish an already encoded message unchanged (relays: echo, replay)."""
        self._publisher.put(payload)
        self.published += 1

    def close(self) -> None:
        """Undeclare the publisher."""
        self._publisher.undeclare()
