"""Typed publishers and subscribers over a Zenoh session.

Zenoh callbacks run on Zenoh's threads, so they only append the raw payload to a bounded
inbox; decoding and all real work happen on the service thread that calls `Inbox.get`.
A payload that fails to decode is counted under (topic, reason), logged once per kind, and
dropped; when the inbox is full the oldest payload is dropped and counted as `overflow`.

Queries take the same road: `serve` queues incoming Zenoh queries for the service thread
to answer, and `catch_up` asks the publishers' queryables for their current value, whose
replies arrive as if they had been published (a service that starts late gets the scenes
published before it subscribed). Liveliness tokens too: `watch` queues their coming and
going, in order with the messages.
"""

from __future__ import annotations

import logging
import math
import secrets
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import zenoh
from google.protobuf.message import Message

from hamnet.runtime import contract
from hamnet.runtime.codec import decode, encode
from hamnet.runtime.tensor import PayloadError

log = logging.getLogger(__name__)

T = TypeVar("T")

CATCH_UP_PERIOD_S = 1.0
"""`Inbox.catch_up` asks the same key at most this often, s (and waits this long for replies)."""

PROCESS_RUN = secrets.randbits(63) + 1
"""This process's run identity, stamped into `header.run` of everything it publishes: new at
every start, never 0 (`hamnet.runtime.freshness` tells restarts from stale steps by it)."""


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
    decode: Callable[[str, Any], Any]
    handle: Any = None
    received: int = 0
    queries: bool = False
    """Items are Zenoh queries handed over as they are, not payloads to decode."""
    tokens: bool = False
    """Items are liveliness changes: True when a token appeared, False when it went away."""


class Inbox:
    """Subscriptions that feed one bounded queue, drained by the service thread."""

    def __init__(self, session: zenoh.Session, drops: DropCounter, capacity: int = 1024) -> None:
        self._session = session
        self._drops = drops
        self._queue: deque[tuple[_Subscription, str, zenoh.ZBytes | zenoh.Query | bool, int]] = (
            deque()
        )
        self._capacity = capacity
        self._ready = threading.Condition()
        self._subscriptions: list[_Subscription] = []
        self._asked: dict[tuple[str, str], float] = {}
        """When each (subscription, key expression) last asked to catch up (monotonic s)."""

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
            decoder = lambda key, payload, mt=message_type: decode(mt, payload, finite)
        subscription = _Subscription(name, decoder)
        origin = zenoh.Locality.REMOTE if remote_only else zenoh.Locality.ANY
        subscription.handle = self._session.declare_subscriber(
            key_expr, lambda sample: self._push(subscription, sample), allowed_origin=origin
        )
        self._subscriptions.append(subscription)

    def serve(self, name: str, key_expr: str) -> None:
        """Queue the Zenoh queries on `key_expr` under the local `name`: `get` returns them
        (value: the `zenoh.Query`) for the service thread to reply to, in order with the
        messages, so that answers read state only that thread touches."""
        subscription = _Subscription(name, lambda key, query: query, queries=True)
        subscription.handle = self._session.declare_queryable(
            key_expr, lambda query: self._push(subscription, query)
        )
        self._subscriptions.append(subscription)

    def watch(self, name: str, key_expr: str) -> None:
        """Queue the liveliness tokens on `key_expr` under the local `name`: `get` returns
        value True for a token that is there (every one present now, then each new one) and
        False for one that went away, in order with the messages, so the service thread sees
        a peer leave after the last message it sent."""
        subscription = _Subscription(name, lambda key, alive: alive, tokens=True)
        subscription.handle = self._session.liveliness().declare_subscriber(
            key_expr, lambda sample: self._push(subscription, sample), history=True
        )
        self._subscriptions.append(subscription)

    def catch_up(self, name: str, key_expr: str, timeout_s: float = CATCH_UP_PERIOD_S) -> None:
        """Ask the queryables on `key_expr` for their current value; each reply is delivered
        to the subscription `name` as if it had been published on the reply's key. Asked
        again before `CATCH_UP_PERIOD_S` has passed, it does nothing: callers ask whenever
        something is missing, and the answer is already on its way."""
        subscription = next((s for s in self._subscriptions if s.name == name), None)
        if subscription is None or subscription.queries or subscription.tokens:
            raise ValueError(f"catch_up needs a subscription named {name!r}")
        now = time.monotonic()
        if now - self._asked.get((name, key_expr), -math.inf) < CATCH_UP_PERIOD_S:
            return
        self._asked[(name, key_expr)] = now

        def on_reply(reply: zenoh.Reply) -> None:
            if reply.ok is not None:
                self._push(subscription, reply.ok)

        # Every reply counts: a replay answers with several scenes on one key, which Zenoh's
        # default consolidation would reduce to one.
        self._session.get(
            key_expr, on_reply, timeout=timeout_s, consolidation=zenoh.ConsolidationMode.NONE
        )

    def _push(self, subscription: _Subscription, sample: zenoh.Sample | zenoh.Query) -> None:
        if subscription.queries:
            payload = sample
        elif subscription.tokens:
            payload = sample.kind == zenoh.SampleKind.PUT
        else:
            payload = sample.payload
        item = (subscription, str(sample.key_expr), payload, time.monotonic_ns())
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
            data = payload.to_bytes() if isinstance(payload, zenoh.ZBytes) else payload
            try:
                value = subscription.decode(key, data)
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
        """A publisher of `key`; it blocks rather than drops under congestion when the
        contract says the topic is lossless."""
        self.key = key
        self.source = source
        self.published = 0
        topic = contract.match_key(key)
        block = topic is not None and topic.lossless
        congestion = zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP
        self._publisher = session.declare_publisher(key, congestion_control=congestion)

    def put(self, message: Message) -> None:
        """Encode and publish; fills `header.source`, `header.stamp_ns` and `header.run`
        (`PROCESS_RUN`) where unset.

        Set fields are kept, so a message forwarded unchanged (echo, replay) stays equal.
        """
        self.put_encoded(self._stamped(message))

    def answer(self, query: zenoh.Query, message: Message) -> None:
        """Reply to a query (queued by `Inbox.serve`) with `message` on this key, stamped as
        `put` would, and finish the query."""
        query.reply(self.key, self._stamped(message))
        query.drop()

    def _stamped(self, message: Message) -> bytes:
        if "header" in message.DESCRIPTOR.fields_by_name:
            header = message.header
            header.source = header.source or self.source
            header.stamp_ns = header.stamp_ns or time.time_ns()
            header.run = header.run or PROCESS_RUN
        return encode(message)

    @property
    def matching(self) -> bool:
        """Whether a subscriber that this session knows of matches the key (Zenoh's matching
        status): a put before then reaches no one."""
        return self._publisher.matching_status.matching

    def put_encoded(self, payload: bytes) -> None:
        """Publish an already encoded message unchanged (relays: echo, replay)."""
        self._publisher.put(payload)
        self.published += 1

    def close(self) -> None:
        """Undeclare the publisher."""
        self._publisher.undeclare()
