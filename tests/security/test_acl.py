"""The access rules built from the contract, and the router config committed from them."""

from __future__ import annotations

import json
from pathlib import Path

import zenoh

from hamnet.launcher.check import check
from hamnet.launcher.stack import load
from hamnet.security.acl import MEMBER, OWNERS, router_config_text, stack_acl

SECURE = Path(__file__).resolve().parents[2] / "compose" / "secure"


def test_committed_router_config_is_the_generated_one() -> None:
    """compose/secure/router.json5 is generated from the contract: a topic added or an
    owner changed without regenerating it would leave the router on stale rules."""
    assert (SECURE / "router.json5").read_text() == router_config_text()


def test_zenoh_accepts_the_rules_and_every_owned_topic_has_one_publisher() -> None:
    config = zenoh.Config.from_file(str(SECURE / "router.json5"))
    acl = json.loads(config.get_json("access_control"))
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    grants = {p["subjects"][0]: p["rules"] for p in stack_acl()["policies"]}
    for path, owner in OWNERS.items():
        holders = [who for who, rules in grants.items() if f"publish {path}" in rules]
        assert holders == [owner]
    open_rule = next(r for r in acl["rules"] if r["id"] == "publish open topics")
    assert not any(word in k for k in open_rule["key_exprs"]
                   for word in ("command", "weights", "estop", "bridge/*/event", "bridge/*/reset"))  # fmt: skip


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
    """The real robot's bridge (issue 17) may publish the robot's topics, its own health and
    events, serve its reset, and subscribe to safety's commands and perception's object pose
    estimate only (each published by its owner alone); it is not a member, which may do more. (A real
    router with these rules: tests/security/test_secure_stack.py.)"""
    acl = stack_acl()
    rules = {rule["id"]: rule for rule in acl["rules"]}
    grants = {policy["subjects"][0]: policy["rules"] for policy in acl["policies"]}
    inbound = [rules[r] for r in grants["bridge"] if rules[r]["flows"] == ["ingress"]]

    def keys_of(messages: set[str]) -> set[str]:
        return {
            key for rule in inbound if messages & set(rule["messages"]) for key in rule["key_exprs"]
        }

    assert keys_of({"put", "delete", "reply", "declare_queryable"}) == {
        "hamnet/*/sim/*/state", "hamnet/*/sim/*/scene", "hamnet/*/sim/*/transition",
        "hamnet/*/health/bridge/*", "hamnet/*/bridge/*/event", "hamnet/*/bridge/*/reset"}  # fmt: skip
    assert keys_of({"declare_subscriber", "declare_liveliness_subscriber", "query",
                    "liveliness_query"}) == {"hamnet/*/safety/*/command",
                                             "hamnet/*/perception/*/object_pose"}  # fmt: skip
    assert keys_of({"liveliness_token"}) == {"hamnet/*/alive/bridge/*"}
    member = next(s for s in acl["subjects"] if s["id"] == MEMBER)["cert_common_names"]
    assert "bridge" not in member and {"sim", "safety", "trainer", "up", "operator"} <= set(member)
