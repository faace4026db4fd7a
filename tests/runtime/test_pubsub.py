"""Typed publishers and inboxes over real Zenoh sessions on loopback (one process)."""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest
import zenoh

from hamnet.proto import sim_pb2
from hamnet.runtime import contract
from hamnet.runtime.pubsub import CATCH_UP_PERIOD_S, DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import to_tensor
from hamnet.runtime.transport import TransportConfig, open_session

STATE = contract.topic("sim/<w>/state")


@pytest.fixture
def sessions(transport: TransportConfig) -> Iterator[tuple[zenoh.Session, zenoh.Session]]:
    first, second = open_session(transport), open_session(transport)
    yield first, second
    first.close()
    second.close()


def state_message(batch: int = 4, value: float = 1.0) -> sim_pb2.RobotState:
    message = sim_pb2.RobotState()
    to_tensor(np.full((batch, 7), value, np.float32), message.q)
    return message


def wait_connected(publish: zenoh.Session, inbox: Inbox, key: str) -> None:
    """Publish probes until the inbox sees one (discovery takes a few ms)."""
    raw = publish.declare_publisher(key)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        raw.put(state_message().SerializeToString())
        if inbox.get(timeout=0.05) is not None:
            while inbox.get(timeout=0.05) is not None:
                pass
            raw.undeclare()
            return
    raise AssertionError("sessions never connected")


def test_messages_arrive_decoded_and_stamped(sessions, transport: TransportConfig) -> None:
    sender, receiver = sessions
    key = STATE.key(transport.namespace, w="0")
    inbox = Inbox(receiver, DropCounter())
    inbox.subscribe("state", key, sim_pb2.RobotState)
    wait_connected(sender, inbox, key)
    publisher = Publisher(sender, key, "sim/0")
    publisher.put(state_message(value=3.0))
    received = inbox.get(timeout=5)
    assert received is not None and received.name == "state" and received.key == key
    assert received.value.header.source == "sim/0" and received.value.header.stamp_ns > 0
    assert received.value.q.data == np.full((4, 7), 3.0, np.float32).tobytes()
    assert publisher.published == 1 and inbox.received["state"] >= 2


def test_bad_payloads_are_counted_by_reason_and_dropped(sessions, transport) -> None:
    sender, receiver = sessions
    key = STATE.key(transport.namespace, w="0")
    drops = DropCounter()
    inbox = Inbox(receiver, drops)
    inbox.subscribe("state", key, sim_pb2.RobotState)
    wait_connected(sender, inbox, key)
    raw = sender.declare_publisher(key)
    raw.put(b"\xff\xfe garbage")
    raw.put(state_message(value=np.nan).SerializeToString())
    raw.put(state_message(value=7.0).SerializeToString())
    received = inbox.get(timeout=5)
    assert received is not None and received.value.q.data[:4] == np.float32(7.0).tobytes()
    assert drops.counts == {(key, "decode"): 1, (key, "nonfinite"): 1}


def test_a_full_inbox_drops_the_oldest_and_counts_overflow(sessions, transport) -> None:
    sender, receiver = sessions
    key = STATE.key(transport.namespace, w="0")
    drops = DropCounter()
    inbox = Inbox(receiver, drops, capacity=3)
    inbox.subscribe("state", key, sim_pb2.RobotState)
    wait_connected(sender, inbox, key)
    publisher = Publisher(sender, key, "sim/0")
    before = inbox.received["state"]
    for value in range(10):
        publisher.put(state_message(value=float(value)))
    deadline = time.monotonic() + 5
    while inbox.received["state"] < before + 10 and time.monotonic() < deadline:
        time.sleep(0.01)
    values = []
    while (received := inbox.get(timeout=0.2)) is not None:
        values.append(np.frombuffer(received.value.q.data, np.float32)[0])
    assert values == [7.0, 8.0, 9.0]
    assert drops.counts[(key, "overflow")] == 7


def test_get_returns_none_after_its_timeout(sessions, transport) -> None:
    inbox = Inbox(sessions[1], DropCounter())
    inbox.subscribe("state", STATE.key(transport.namespace, w="0"), sim_pb2.RobotState)
    started = time.monotonic()
    assert inbox.get(timeout=0.1) is None
    assert time.monotonic() - started >= 0.1


def test_a_late_subscriber_catches_up_through_the_publishers_queryable(sessions, transport) -> None:
    """The publisher's side queues the query for its own thread (`serve`) and answers with
    its current value; the late side receives that reply decoded under its subscription, as
    if it had been published (what a perception service started after the sim relies on)."""
    publisher_side, late_side = sessions
    key = STATE.key(transport.namespace, w="0")
    served = Inbox(publisher_side, DropCounter())
    served.serve("state_query", key)
    late = Inbox(late_side, DropCounter())
    late.subscribe("state", key, sim_pb2.RobotState)
    deadline = time.monotonic() + 10
    answered = None
    while answered is None and time.monotonic() < deadline:
        late.catch_up("state", key, timeout_s=0.5)
        query = served.get(timeout=0.5)
        if query is None:
            continue
        assert query.name == "state_query" and isinstance(query.value, zenoh.Query)
        query.value.reply(key, state_message(value=7.0).SerializeToString())
        query.value.drop()
        answered = late.get(timeout=5)
    assert answered is not None and answered.name == "state" and answered.key == key
    assert answered.value.q.data == np.full((4, 7), 7.0, np.float32).tobytes()
    with pytest.raises(ValueError, match="subscription named"):
        late.catch_up("nothing", key)


def test_catching_up_again_within_the_period_asks_nothing(sessions, transport) -> None:
    """Shells ask whenever a state misses its scene, up to every message: the inbox sends
    one query per `CATCH_UP_PERIOD_S`, not one per call."""
    publisher_side, late_side = sessions
    key = STATE.key(transport.namespace, w="0")
    served = Inbox(publisher_side, DropCounter())
    served.serve("state_query", key)
    late = Inbox(late_side, DropCounter())
    late.subscribe("state", key, sim_pb2.RobotState)
    deadline = time.monotonic() + 10
    first = None
    while first is None:  # discovery: ask until the queryable is reached
        assert time.monotonic() < deadline, "the queryable was never reached"
        late.catch_up("state", key)
        first = served.get(timeout=0.2)
        if first is None:
            time.sleep(CATCH_UP_PERIOD_S)
    first.value.drop()
    for _ in range(5):
        late.catch_up("state", key)
    assert served.get(timeout=0.3) is None


def test_watched_tokens_come_and_go_in_order_with_the_messages(sessions, transport) -> None:
    """The trainer learns that a rollout worker left from `watch`: a token present before
    the watch starts is reported, and its withdrawal and the owner's last message both
    arrive. Zenoh orders neither before the other (data and liveliness travel apart; a
    fresh clone's run once saw the withdrawal first), so the order is not asserted: a chunk
    that comes after its worker's token went is counted by the trainer, not relied on."""
    owner, watcher = sessions
    alive = contract.topic("alive/<service>/<w>")
    key = alive.key(transport.namespace, service="rollout", w="3")
    state = STATE.key(transport.namespace, w="3")
    token = owner.liveliness().declare_token(key)
    inbox = Inbox(watcher, DropCounter())
    inbox.subscribe("state", state, sim_pb2.RobotState)
    inbox.watch("alive", alive.pattern_in(transport.namespace))
    first = inbox.get(timeout=10)
    assert first is not None and (first.name, first.key, first.value) == ("alive", key, True)
    wait_connected(owner, inbox, state)
    Publisher(owner, state, "rollout/3").put(state_message())
    token.undeclare()
    names = [(r.name, r.value if r.name == "alive" else None)
             for r in iter(lambda: inbox.get(timeout=5), None)][:2]  # fmt: skip
    assert sorted(names) == [("alive", False), ("state", None)]
    with pytest.raises(ValueError, match="catch_up"):
        inbox.catch_up("alive", key)


def test_publishers_of_lossless_topics_block_and_the_others_drop(sessions, transport) -> None:
    """Weights, rollouts and scenes must arrive whole; a late state or command is stale
    anyway."""
    session, _ = sessions
    ns = transport.namespace
    weights = Publisher(session, contract.topic("trainer/weights").key(ns), "trainer")
    scene = Publisher(session, contract.topic("sim/<w>/scene").key(ns, w="0"), "sim/0")
    state = Publisher(session, contract.topic("sim/<w>/state").key(ns, w="0"), "sim/0")
    assert weights._publisher.congestion_control == zenoh.CongestionControl.BLOCK
    assert scene._publisher.congestion_control == zenoh.CongestionControl.BLOCK
    assert state._publisher.congestion_control == zenoh.CongestionControl.DROP
