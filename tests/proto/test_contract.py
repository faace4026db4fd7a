"""The topic contract: keys, patterns and message types."""

from __future__ import annotations

import pytest

from hamnet.runtime import contract
from hamnet.runtime.codec import decode, encode
from tests.messages import random_message


@pytest.mark.parametrize("topic", contract.MESSAGE_TOPICS, ids=lambda t: t.path)
def test_every_message_type_round_trips_through_bytes(topic: contract.Topic) -> None:
    message = random_message(topic.message, seed=len(topic.path))
    assert decode(topic.message, encode(message), topic.finite) == message


@pytest.mark.parametrize("topic", contract.TOPICS, ids=lambda t: t.path)
def test_concrete_keys_match_their_own_topic_only(topic: contract.Topic) -> None:
    key = topic.key("ns1", **{name: "x7" for name in topic.placeholders})
    assert contract.match_key(key) is topic


def test_keys_reject_wildcards_and_slashes() -> None:
    state = contract.topic("sim/<w>/state")
    assert state.key("default", w="0") == "hamnet/default/sim/0/state"
    for bad in ("*", "a/b", "", "$x"):
        with pytest.raises(ValueError):
            state.key("default", w=bad)
        with pytest.raises(ValueError):
            state.key(bad, w="0")


def test_keys_outside_the_contract_do_not_match() -> None:
    assert contract.match_key("hamnet/default/sim/0/unknown") is None
    assert contract.match_key("other/default/sim/0/state") is None
    assert contract.match_key("hamnet/default/sim/state") is None
