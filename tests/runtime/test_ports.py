"""Ports: a shell's local names resolve to its own keys, and `--remap` rewires them to other
keys of the same topic only."""

from __future__ import annotations

import pytest

from hamnet.runtime.errors import ConfigError
from hamnet.runtime.ports import Ports

PORTS = Ports(inputs={"state": "sim/<w>/state", "weights": "trainer/weights"},
              outputs={"action": "policy/<w>/action"})  # fmt: skip


def test_every_port_is_its_topics_key_for_this_namespace_and_worker() -> None:
    assert PORTS.keys("ns", w="3") == {"state": "hamnet/ns/sim/3/state",
                                       "weights": "hamnet/ns/trainer/weights",
                                       "action": "hamnet/ns/policy/3/action"}  # fmt: skip


def test_a_remap_takes_a_whole_key_or_a_path_in_the_namespace() -> None:
    keys = PORTS.keys("ns", ("state=hamnet/replay/sim/0/state", "action=policy/7/action"), w="3")
    assert keys["state"] == "hamnet/replay/sim/0/state"
    assert keys["action"] == "hamnet/ns/policy/7/action"
    assert keys["weights"] == "hamnet/ns/trainer/weights"


@pytest.mark.parametrize(
    ("entry", "message"),
    [("tokens=sim/0/state", "no port 'tokens'; the ports are state, weights, action"),
     ("state", "--remap takes PORT=KEY"),
     ("state=", "--remap takes PORT=KEY"),
     ("state=policy/0/action", "carries hamnet/<ns>/sim/<w>/state"),
     ("weights=hamnet/other/trainer/schedule", "not one of its keys")],
)  # fmt: skip
def test_a_remap_to_an_unknown_port_or_another_topic_is_refused(entry: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        PORTS.keys("ns", (entry,), w="0")


def test_ports_outside_the_contract_or_declared_twice_are_refused() -> None:
    with pytest.raises(KeyError, match="no topic"):
        Ports(inputs={"state": "sim/<w>/states"}, outputs={})
    with pytest.raises(ValueError, match="inputs and outputs"):
        Ports(inputs={"state": "sim/<w>/state"}, outputs={"state": "sim/<w>/state"})


def test_help_lists_each_port_with_its_direction_and_topic() -> None:
    text = PORTS.describe()
    assert "--remap PORT=KEY" in text
    assert (
        "state        in   sim/<w>/state" in text and "action       out  policy/<w>/action" in text
    )
