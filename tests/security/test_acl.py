"""The access rules generated from the contract, and the router config committed from them."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import zenoh

from hamnet.cli import COMMANDS
from hamnet.launcher.check import check
from hamnet.launcher.stack import load
from hamnet.runtime import contract
from hamnet.security.acl import identities, router_config_text, stack_acl
from hamnet.tools.echo import reflect_key

SECURE = Path(__file__).resolve().parents[2] / "compose" / "secure"

PUBLISHING = {"put", "delete", "reply", "declare_queryable", "liveliness_token"}
"""Every message that makes data (or a token) appear on a key."""

EVERYONE = sorted({command.name for command in COMMANDS} | {contract.OPERATOR, "intruder"})
"""Every name a certificate of the stack's CA may carry: the commands', the operator's and
one of no identity."""


class Rights:
    """What the generated rules let each certificate name send to the router."""

    def __init__(self, acl: dict) -> None:
        rules = {rule["id"]: rule for rule in acl["rules"]}
        names = {s["id"]: s["cert_common_names"] for s in acl["subjects"]}
        self.inbound: dict[str, list[dict]] = {name: [] for name in EVERYONE}
        for policy in acl["policies"]:
            ingress = [rules[r] for r in policy["rules"] if rules[r]["flows"] == ["ingress"]]
            for subject in policy["subjects"]:
                for name in names[subject]:
                    self.inbound.setdefault(name, []).extend(ingress)

    def allows(self, who: str, messages: set[str], key_expr: str) -> bool:
        """Whether one rule of `who` lets one of `messages` through on all of `key_expr` (as
        the router decides: a rule's key expression must include the message's)."""
        key = zenoh.KeyExpr(key_expr)
        return any(messages & set(rule["messages"]) and zenoh.KeyExpr(k).includes(key)
                   for rule in self.inbound[who] for k in rule["key_exprs"])  # fmt: skip

    def touches(self, who: str, messages: set[str], key_expr: str) -> bool:
        """Whether one rule of `who` lets one of `messages` through on any key of `key_expr`."""
        key = zenoh.KeyExpr(key_expr)
        return any(messages & set(rule["messages"]) and zenoh.KeyExpr(k).intersects(key)
                   for rule in self.inbound[who] for k in rule["key_exprs"])  # fmt: skip


def reading(topic: contract.Topic) -> set[str]:
    """The messages that read `topic`: subscribing, asking a latch, watching tokens."""
    if topic.queryable:
        return {"query"}
    if topic.message is None:
        return {"declare_liveliness_subscriber", "liveliness_query"}
    return {"declare_subscriber"}


def own_keys(topic: contract.Topic) -> dict[str, set[str]]:
    """Key expressions of `topic` in namespace `ns`, each with who alone may publish it: for
    a `<service>` topic one per service (and one for names that are none), else the topic's."""
    pattern = topic.pattern_in("ns")
    if "service" not in topic.placeholders:
        return {pattern: set(topic.publishers)}
    segment = topic.path.split("/").index("<service>") + 2
    owners = {}
    for name in (*topic.publishers, contract.OPERATOR, "intruder"):
        parts = pattern.split("/")
        parts[segment] = name
        owners["/".join(parts)] = {name} & set(topic.publishers)
    return owners


def test_committed_router_config_is_the_generated_one() -> None:
    """compose/secure/router.json5 is generated from the contract: a topic added or a
    publisher changed without regenerating it would leave the router on stale rules."""
    assert (SECURE / "router.json5").read_text() == router_config_text()


def test_zenoh_accepts_the_rules() -> None:
    config = zenoh.Config.from_file(str(SECURE / "router.json5"))
    acl = json.loads(config.get_json("access_control"))
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    rules, subjects = {r["id"] for r in acl["rules"]}, {s["id"] for s in acl["subjects"]}
    assert len(rules) == len(acl["rules"]) and len(subjects) == len(acl["subjects"])
    used = {r for p in acl["policies"] for r in p["rules"]}
    assert used == rules and {s for p in acl["policies"] for s in p["subjects"]} == subjects


@pytest.mark.parametrize("topic", contract.TOPICS, ids=lambda t: t.path)
def test_only_the_contracts_publishers_publish_and_only_its_readers_read(
    topic: contract.Topic,
) -> None:
    """Issue 29: a valid certificate of the monitor or of the trainer published robot states
    that the policy and safety took for the sim's. Now every key may be published (or
    served, or its token declared) by exactly the identities its contract entry names,
    each service its health and token under its own name only, and read (subscribed,
    asked, watched) by exactly its readers; every other name, a command's or not, is
    refused."""
    rights = Rights(stack_acl())
    for key_expr, owners in own_keys(topic).items():
        for who in EVERYONE:
            publisher = who in owners
            assert rights.allows(who, PUBLISHING, key_expr) == publisher, (who, key_expr)
            assert rights.touches(who, PUBLISHING, key_expr) == publisher, (who, key_expr)
    pattern = topic.pattern_in("ns")
    for who in EVERYONE:
        reader = who in topic.readers
        assert rights.allows(who, reading(topic), pattern) == reader, (who, pattern)
        assert rights.touches(who, reading(topic), pattern) == reader, (who, pattern)
        if topic.message is not None:  # readers ask for the latest value where it is served
            asks = reader and topic.catch_up
            assert rights.touches(who, {"query"}, pattern) == asks, (who, pattern)


def test_names_the_contract_does_not_know_get_nothing() -> None:
    """A certificate under a name of no identity (`intruder`, or a command that never joins
    the stack) matches no subject: the router drops all its messages."""
    named = {name for s in stack_acl()["subjects"] for name in s["cert_common_names"]}
    assert named == set(identities()) and set(identities()) <= set(EVERYONE)
    assert {"intruder", "pretrain", "certs", "topics"}.isdisjoint(named)
    assert set(contract.SERVICES) <= {command.name for command in COMMANDS}


def test_the_observers_read_everything_and_echo_reflects_under_its_own_keys() -> None:
    """`record` and `echo` subscribe to the whole namespace, as they do; echo's reflections
    go under `echo/`, which is no topic's key (so no topic gains a publisher by it)."""
    rights = Rights(stack_acl())
    for who in EVERYONE:
        assert rights.allows(who, {"declare_subscriber"}, "hamnet/ns/**") == (
            who in contract.OBSERVERS)  # fmt: skip
    reflected = reflect_key("ns", "0", contract.topic("sim/<w>/state").key("ns", w="0"))
    assert [who for who in EVERYONE if rights.allows(who, {"put"}, reflected)] == ["echo"]


def test_only_the_operator_asks_the_latches_and_each_has_one_server() -> None:
    """Safety's e-stop and the bridge's robot-error reset: a reset from anyone but the
    operator would release a stopped robot."""
    acl = stack_acl()
    rules = {rule["id"]: rule for rule in acl["rules"]}
    grants = {p["subjects"][0]: p["rules"] for p in acl["policies"]}
    askers = [who for who, ids in grants.items()
              if any("query" in rules[r]["messages"] and "hamnet/*/bridge/*/reset" in rules[r]["key_exprs"]
                     for r in ids)]  # fmt: skip
    assert askers == ["operator"]
    servers = {who: [r for r in ids if r.startswith("serve ")] for who, ids in grants.items()}
    assert servers["safety"] == ["serve safety/<w>/estop"]
    assert servers["bridge"] == ["serve bridge/<w>/reset"]


def test_secure_stack_file_is_valid() -> None:
    stack = load(SECURE / "stack.yaml")
    assert {verdict.status for verdict in check(stack, {})} == {"ok"}


def test_the_bridge_publishes_the_robot_and_hears_only_safety() -> None:
    """The real robot's bridge (issue 17) may publish the robot's state, its own health and
    events, serve its reset, and subscribe to safety's commands and perception's object pose
    estimate only (each published by its owner alone). (Before issue 29 it could also
    publish scenes and transitions, which it does not: the contract now names the sim alone
    for them.) A real router with these rules: tests/security/test_secure_stack.py."""
    acl = stack_acl()
    rules = {rule["id"]: rule for rule in acl["rules"]}
    grants = {policy["subjects"][0]: policy["rules"] for policy in acl["policies"]}
    inbound = [rules[r] for r in grants["bridge"] if rules[r]["flows"] == ["ingress"]]

    def keys_of(messages: set[str]) -> set[str]:
        return {
            key for rule in inbound if messages & set(rule["messages"]) for key in rule["key_exprs"]
        }

    assert keys_of({"put", "delete", "reply", "declare_queryable"}) == {
        "hamnet/*/sim/*/state", "hamnet/*/health/bridge/*", "hamnet/*/bridge/*/event",
        "hamnet/*/bridge/*/reset"}  # fmt: skip
    assert keys_of({"declare_subscriber", "declare_liveliness_subscriber", "query",
                    "liveliness_query"}) == {"hamnet/*/safety/*/command",
                                             "hamnet/*/perception/*/object_pose"}  # fmt: skip
    assert keys_of({"liveliness_token"}) == {"hamnet/*/alive/bridge/*"}
    assert "bridge" not in contract.OBSERVERS


def test_the_docs_table_of_rights_is_the_contracts() -> None:
    """docs/security.md lists every topic with its publishers and readers (the observers,
    which read everything, said once below the table)."""
    docs = (Path(__file__).resolve().parents[2] / "docs" / "security.md").read_text()
    rows = {}
    for line in docs.splitlines():
        cells = [cell.strip() for cell in line.strip("|").split("|")]
        match = re.fullmatch(r"`([^`]+)`.*", cells[0]) if len(cells) == 3 else None
        if match and contract.match_key(f"hamnet/ns/{match.group(1)}".replace("<w>", "0")
                                        .replace("<service>", "sim")):  # fmt: skip
            rows[match.group(1)] = [set(re.findall(r"`([a-z]+)`", cell)) for cell in cells[1:]]
    assert set(rows) == {t.path for t in contract.TOPICS}
    for topic in contract.TOPICS:
        published, read = rows[topic.path]
        if "service" not in topic.placeholders:
            assert published == set(topic.publishers), topic.path
        assert read == set(topic.readers) - set(contract.OBSERVERS), topic.path
