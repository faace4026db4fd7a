"""Two processes over real Zenoh on loopback: every message type crosses the wire and comes
back equal, and malformed payloads on every topic are counted and dropped while the
receiving service stays up."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Iterator

import numpy as np
import pytest

from hamnet.proto.health_pb2 import Health
from hamnet.runtime import contract, keys
from hamnet.runtime.codec import decode, encode, iter_tensors
from hamnet.runtime.pubsub import DropCounter, Inbox
from hamnet.runtime.tensor import PayloadError, to_tensor
from hamnet.runtime.transport import TransportConfig, open_session
from tests.conftest import transport_args
from tests.messages import random_message


@pytest.fixture
def echo(spawn, transport: TransportConfig) -> Iterator[tuple]:
    """A `hamnet echo --reflect` process and a session of our own on the same stack."""
    process = spawn("echo", "--reflect", "--worker", "e1", *transport_args(transport))
    session = open_session(transport)
    alive = contract.topic("alive/<service>/<w>").key(transport.namespace, service="echo", w="e1")
    deadline = time.monotonic() + 20
    while not list(session.liveliness().get(alive, timeout=1.0)):
        assert process.poll() is None, process.stdout.read()
        assert time.monotonic() < deadline, "echo never announced itself"
        time.sleep(0.1)
    yield process, session
    session.close()


def message_keys(namespace: str) -> list[tuple[contract.Topic, str]]:
    """One concrete key per message topic of the contract."""
    return [
        (topic, topic.key(namespace, **{name: "w0" for name in topic.placeholders}))
        for topic in contract.MESSAGE_TOPICS
    ]


def reflected_from(namespace: str, key: str) -> str:
    """The original key of a message reflected by echo worker e1."""
    return key.replace(f"{keys.ROOT}/{namespace}/echo/e1/reflect/", f"{keys.ROOT}/{namespace}/", 1)


def test_every_message_type_crosses_two_processes_and_decodes_equal(echo, transport) -> None:
    process, session = echo
    namespace = transport.namespace
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("reflected", f"{keys.ROOT}/{namespace}/echo/e1/reflect/**", decoder=lambda k, p: p)
    sent = {
        key: random_message(topic.message, seed=seed)
        for seed, (topic, key) in enumerate(message_keys(namespace))
    }
    pending = set(sent)
    deadline = time.monotonic() + 20
    while pending and time.monotonic() < deadline:
        # Resent until reflected: the first puts may precede route discovery.
        for key in pending:
            session.put(key, encode(sent[key]))
        while (received := inbox.get(timeout=0.2)) is not None:
            original = reflected_from(namespace, received.key)
            if original not in sent:  # echo also reflects its own health reports
                continue
            topic = contract.match_key(original)
            assert decode(topic.message, received.value, topic.finite) == sent[original]
            pending.discard(original)
    assert not pending, f"never reflected: {sorted(pending)}"
    assert process.poll() is None


def malformed_payloads(topic: contract.Topic, rng: np.random.Generator) -> list[bytes]:
    """Random bytes, truncated encodings and tensors with bad dtype, byte count or values."""
    valid = encode(random_message(topic.message, seed=int(rng.integers(1000))))
    payloads = [rng.bytes(int(n)) for n in rng.integers(1, 300, size=15)]
    payloads += [valid[: int(end)] for end in rng.integers(1, len(valid), size=10)]
    for corrupt in ("dtype", "bytes", "nan"):
        message = random_message(topic.message, seed=int(rng.integers(1000)))
        tensors = [tensor for _, tensor in iter_tensors(message)]
        if not tensors:  # schedules, metrics and weights carry no tensors
            break
        tensor = tensors[0]
        if corrupt == "dtype":
            tensor.dtype = 99
        elif corrupt == "bytes":
            tensor.data = tensor.data + b"\0"
        else:
            to_tensor(np.full((2, 3), np.nan, np.float32), tensor)
        payloads.append(encode(message))
    return payloads


def expected_drops(topic: contract.Topic, payloads: list[bytes]) -> Counter[str]:
    """What a correct receiver must drop, by reason, judged in this process."""
    reasons: Counter[str] = Counter()
    for payload in payloads:
        try:
            decode(topic.message, payload, topic.finite)
        except PayloadError as error:
            reasons[error.reason] += 1
    return reasons


def test_malformed_payloads_on_every_topic_are_counted_and_dropped(echo, transport) -> None:
    process, session = echo
    namespace = transport.namespace
    rng = np.random.default_rng(7)
    expected: dict[tuple[str, str], int] = {}
    topics = [(t, k) for t, k in message_keys(namespace) if t.path != "health/<service>/<w>"]
    batches = {key: malformed_payloads(topic, rng) for topic, key in topics}
    for topic, key in topics:
        for reason, count in expected_drops(topic, batches[key]).items():
            expected[(key, reason)] = count
    assert sum(expected.values()) > 20 * len(topics)
    inbox = Inbox(session, DropCounter())
    health_key = contract.topic("health/<service>/<w>").key(namespace, service="echo", w="e1")
    inbox.subscribe("health", health_key, Health)
    inbox.subscribe("reflected", f"{keys.ROOT}/{namespace}/echo/e1/reflect/**", decoder=lambda k, p: k)
    probe_topic, probe_key = topics[0]
    probe = encode(random_message(probe_topic.message, seed=1))
    # Puts made before this session knows echo's subscription are lost: wait for a route.
    deadline = time.monotonic() + 20
    while inbox.get(timeout=0.2) is None or inbox.received["reflected"] == 0:
        assert time.monotonic() < deadline, "echo never reflected the probe"
        session.put(probe_key, probe)
    for key, payloads in batches.items():
        for payload in payloads:
            session.put(key, payload)
    # A valid message after the bad ones: once it is reflected, echo has judged them all.
    counted: dict[tuple[str, str], int] = {}
    deadline = time.monotonic() + 20
    while counted != expected and time.monotonic() < deadline:
        session.put(probe_key, probe)
        while (received := inbox.get(timeout=0.3)) is not None:
            if received.name == "health":
                counted = {(d.key, d.reason): d.count for d in received.value.drops}
    assert counted == expected
    assert process.poll() is None, "echo died on malformed input"
    alive = contract.topic("alive/<service>/<w>").key(namespace, service="echo", w="e1")
    assert list(session.liveliness().get(alive, timeout=2.0))
