"""The stack's access rules as Zenoh's own `access_control` config, generated from the topic
contract (`hamnet.runtime.contract`): who may publish (or answer for) and who may read which
keys, by certificate common name.

Each key may be published by exactly the identities its contract entry names as publishers
(put, delete, and answering queries on it), and read by exactly those it names as readers
(subscribe; query too where its publishers answer queries with the latest value: the
scenes, the weights). A key with a `<service>` segment (health reports, liveliness tokens)
may be published by each service only under its own name. The latches (safety's e-stop,
the bridge's reset) are served by their service and asked by `operator` alone. The
observers (`record`, `echo`), which read every topic, may subscribe to the whole namespace
(`hamnet/<ns>/**`), and `echo` may publish its reflections under `echo/`, a key no service
reads. Any other name, and any other right, gets nothing (default deny): `hamnet replay`
may only report its health, so a replay cannot feed a secure stack (docs/security.md).

Zenoh applies the rules where a link ends, so they belong on the router every service joins
as a client (`compose/secure/`, docs/security.md). `python -m hamnet.security.acl` prints
the router's JSON5 config.
"""

from __future__ import annotations

import json

from hamnet.runtime import contract, keys

MESSAGES = (
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
)
"""Every message type Zenoh's access control filters."""

PUBLISH = ("put", "delete", "reply", "declare_queryable")
"""What makes data appear on a key: publishing it, or answering queries on it."""
SERVE = ("declare_queryable", "reply")
"""Serving a queryable (a latch)."""
ANNOUNCE = ("liveliness_token",)
"""Declaring a liveliness token."""

SUBSCRIBE = ("declare_subscriber",)
"""Reading a topic."""
CATCH_UP = ("declare_subscriber", "query")
"""Reading a topic whose publishers answer queries with the latest value (`Topic.catch_up`)."""
ASK = ("query",)
"""Asking a queryable (a latch: stop, reset, status)."""
WATCH = ("declare_liveliness_subscriber", "liveliness_query")
"""Following liveliness tokens (with the tokens already declared)."""

REFLECTIONS = "echo/*/reflect/**"
"""Where `hamnet echo --reflect` republishes (`hamnet.tools.echo.reflect_key`), after the
namespace: no contract key, read by no service."""
REFLECTOR = "echo"


def identities() -> list[str]:
    """Every identity the contract names (publishers and readers), sorted."""
    return sorted({name for t in contract.TOPICS for name in (*t.publishers, *t.readers)})


def publish_rights(topic: contract.Topic) -> tuple[str, ...]:
    """The messages a publisher of `topic` may send on its keys."""
    if topic.queryable:
        return SERVE
    return PUBLISH if topic.message is not None else ANNOUNCE


def read_rights(topic: contract.Topic) -> tuple[str, ...]:
    """The messages a reader of `topic` may send on its keys."""
    if topic.queryable:
        return ASK
    if topic.message is None:
        return WATCH
    return CATCH_UP if topic.catch_up else SUBSCRIBE


def stack_acl(namespace: str = "*") -> dict[str, object]:
    """Zenoh `access_control` config for a stack in `namespace` ('*': any).

    Returns:
        A dict for the `access_control` key of a Zenoh config (default deny).
    """
    everything = f"{keys.ROOT}/{namespace}/**"
    rules = [_rule("deliver", MESSAGES, [everything], flow="egress")]
    grants: dict[str, list[str]] = {name: ["deliver"] for name in identities()}
    for topic in contract.TOPICS:
        verb = "serve" if topic.queryable else "publish"
        if "service" in topic.placeholders:  # each publisher under its own name only
            for name in topic.publishers:
                rule_id = f"{verb} {topic.path.replace('<service>', name)}"
                rules.append(_rule(rule_id, publish_rights(topic), [_own(topic, namespace, name)]))
                grants[name].append(rule_id)
        else:
            rule_id = f"{verb} {topic.path}"
            rules.append(_rule(rule_id, publish_rights(topic), [topic.pattern_in(namespace)]))
            for name in topic.publishers:
                grants[name].append(rule_id)
        rule_id = f"{'ask' if topic.queryable else 'read'} {topic.path}"
        rules.append(_rule(rule_id, read_rights(topic), [topic.pattern_in(namespace)]))
        for name in topic.readers:
            grants[name].append(rule_id)
    rules.append(_rule("observe the stack", SUBSCRIBE, [everything]))
    for name in contract.OBSERVERS:
        grants[name].append("observe the stack")
    rules.append(_rule("reflect", ("put", "delete"), [f"{keys.ROOT}/{namespace}/{REFLECTIONS}"]))
    grants[REFLECTOR].append("reflect")
    subjects = [{"id": name, "cert_common_names": [name]} for name in grants]
    policies = [
        {"id": f"{name} may", "rules": rules_, "subjects": [name]}
        for name, rules_ in grants.items()
    ]
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def _own(topic: contract.Topic, namespace: str, service: str) -> str:
    """Key expression of `topic` (a `<service>` key) for `service` only, any other field."""
    segments = (
        service if s == "<service>" else "*" if s.startswith("<") else s
        for s in topic.path.split("/")
    )
    return "/".join((keys.ROOT, namespace, *segments))


def _rule(
    rule_id: str, messages: tuple[str, ...], key_exprs: list[str], flow: str = "ingress"
) -> dict[str, object]:
    return {
        "id": rule_id,
        "messages": list(messages),
        "flows": [flow],
        "permission": "allow",
        "key_exprs": key_exprs,
    }


def router_config_text(namespace: str = "*") -> str:
    """A router's Zenoh JSON5 config holding the stack's access rules (TLS comes from the
    router's --tls-dir)."""
    header = (
        "// Generated by `python -m hamnet.security.acl`: the stack's access rules\n"
        "// (docs/security.md). Use with hamnet router --tls-dir D --zenoh-config this.\n"
    )
    return header + json.dumps({"access_control": stack_acl(namespace)}, indent=2) + "\n"


if __name__ == "__main__":
    print(router_config_text(), end="")
