"""A scripted stand-in for `hamnet.runtime.service.Service`, to drive a service shell's loop
with a list of messages instead of a network (dora's MockNode idea), and capture what it
publishes."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

from hamnet.runtime.codec import decode, encode
from hamnet.runtime.pubsub import DropCounter, Received
from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.runtime.tensor import PayloadError


def wire(message, finite: bool = True):
    """Through the wire format, checked the way a generic receiver checks it."""
    return decode(type(message), encode(message), finite)


class CapturingPublisher:
    """Keeps what is put, through the wire format, under the topic's last key segment."""

    def __init__(
        self, key: str, published: list[tuple[str, object]], subscribed: Callable[[], bool]
    ) -> None:
        self.topic, self.published, self._subscribed = key.rsplit("/", 1)[1], published, subscribed

    @property
    def matching(self) -> bool:
        """Whether a subscriber is known (the scripted network's `subscribed`)."""
        return self._subscribed()

    def put(self, message) -> None:
        self.published.append((self.topic, wire(message)))

    def answer(self, query: list, message) -> None:
        """A scripted query is a list that collects its answers."""
        query.append(wire(message))


class _Queryable:
    def undeclare(self) -> None:
        pass


class _Session:
    def declare_queryable(self, key: str, handler) -> _Queryable:
        return _Queryable()


@dataclass
class ScriptedService:
    """Stands in for `Service`: `receive` asks `script` for the next (name, payload) given
    what was published so far and decodes it with the shell's own decoder (counting a
    PayloadError as the inbox does). The script returns "end" to stop the loop; when it has
    nothing (None) the loop stops too, or, with `idle`, the timeout is waited out as a quiet
    network would."""

    script: Callable[[list[tuple[str, object]]], tuple[str, bytes] | str | None]
    identity: ServiceIdentity = field(default_factory=lambda: ServiceIdentity("sim", "0"))
    idle: bool = False
    namespace: str = "t"
    published: list[tuple[str, object]] = field(default_factory=list)
    drops: DropCounter = field(default_factory=DropCounter)
    session: _Session = field(default_factory=_Session)
    running: bool = True
    caught_up: list[tuple[str, str]] = field(default_factory=list)
    events: Counter[str] = field(default_factory=Counter)
    remap: tuple[str, ...] = ()
    subscribed: Callable[[], bool] = lambda: True
    """What every publisher's `matching` answers now."""

    ports = Service.ports  # the real resolution of a shell's ports, from the fields above

    def __post_init__(self) -> None:
        self.inbox, self.decoders = self, {}

    def subscribe(self, name: str, key: str, decoder) -> None:
        self.decoders[name] = (key, decoder)

    def catch_up(self, name: str, key: str) -> None:
        """Recorded in `caught_up`: a scripted network has nobody to answer."""
        self.caught_up.append((name, key))

    def serve(self, name: str, key: str) -> None:
        """Queries under `name` are scripted as (name, list): the list collects the answers."""
        self.decoders[name] = (key, lambda key, query: query)

    def publisher(self, key: str) -> CapturingPublisher:
        return CapturingPublisher(key, self.published, self.subscribed)

    def count_event(self, name: str, count: int = 1) -> None:
        self.events[name] += count

    def receive(self, timeout: float = 0.1) -> Received | None:
        while (item := self.script(self.published)) is not None:
            if item == "end":
                self.running = False
                return None
            name, payload = item
            key, decoder = self.decoders[name]
            try:
                return Received(name, key, decoder(key, payload), 0)
            except PayloadError as error:
                self.drops.drop(key, error.reason, error.detail)
        if self.idle:
            time.sleep(timeout)
        else:
            self.running = False
        return None
