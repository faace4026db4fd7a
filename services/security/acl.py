"""The stack's access rules as Zenoh's own `access_control` config, built from the topic
contract: who may publish (or answer for) which keys, by certificate common name.

Every identity named after a `hamnet` command (and `operator`) may subscribe to everything
and publish the open topics; only `safety` may publish commands, only `trainer` weights and
the step counter (schedule), only `camera` depth frames (perception's view of the
world), only `perception` the object pose estimate, and only `operator` may use the e-stop (which `safety` serves)
and the bridge's reset. The real robot's `bridge` may only publish the robot's topics
(state, scene, transition) and its own events, serve its reset, and subscribe to safety's
commands and perception's object pose estimate; any other name gets nothing. Zenoh applies the rules where
a link ends, so they belong on the router every service joins as a client
(`compose/secure/`, docs/security.md). `python -m hamnet.security.acl` prints the router's
JSON5 config.
"""

from __future__ import annotations

import json

from hamnet.cli import COMMANDS
from hamnet.runtime import contract, keys

MESSAGES = ("put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
            "liveliness_token", "declare_liveliness_subscriber", "liveliness_query")  # fmt: skip
"""Every message type Zenoh's access control filters."""

PUBLISH = ("put", "delete", "reply", "declare_queryable")
"""What makes data appear on a key: publishing it, or answering queries on it."""

LISTEN = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_token",
          "liveliness_query")  # fmt: skip
"""Subscribing and liveliness: open to every member on every key of the stack."""

OWNERS: dict[str, str] = {
    "safety/<w>/command": "safety",
    "trainer/weights": "trainer",
    "trainer/schedule": "trainer",
    "bridge/<w>/event": "bridge",
    "camera/<w>/frames": "camera",
    "perception/<w>/object_pose": "perception",
}
"""Topics one identity alone may publish; everyone may still read (and query) them."""

SERVED: dict[str, str] = {
    "safety/<w>/estop": "safety",
    "bridge/<w>/reset": "bridge",
}
"""The latches and who serves them: safety's e-stop and the bridge's robot-error reset."""
REQUESTER = "operator"
"""The one identity that may ask a latch (stop, reset, status): a stop from anyone else
would be a denial of service, a reset a release of a stopped robot."""

BRIDGE = "bridge"
ROBOT = ("sim/<w>/state", "sim/<w>/scene", "sim/<w>/transition")
"""What the real robot's bridge (issue 17) may publish, or answer queries on: the robot's
topics, which it publishes in place of the sim; and its own health and liveliness token."""
BRIDGE_HEARS = ("safety/<w>/command", "perception/<w>/object_pose")
"""What the bridge may subscribe to: the commands only safety may publish, and the object
pose estimate only perception may publish (it goes into the robot's state)."""
BOOKKEEPING = ("health/<service>/<w>", "alive/<service>/<w>")
"""Every service's own health reports and liveliness token."""

OPERATOR = "operator"
MEMBER = "member"
"""Subject of every identity named after a `hamnet` command (and `operator`) but the
bridge: a certificate of the stack's CA under another name gets nothing, and the bridge
only its own rules (Zenoh's allow rules add up; a deny rule cannot take back what a
default-deny config allowed)."""


def members() -> list[str]:
    """Names of the MEMBER subject: every `hamnet` command but the bridge, and the operator."""
    return sorted({command.name for command in COMMANDS} - {BRIDGE} | {OPERATOR})


def stack_acl(namespace: str = "*") -> dict[str, object]:
    """Zenoh `access_control` config for a stack in `namespace` ('*': any).

    Returns:
        A dict for the `access_control` key of a Zenoh config (default deny).
    """
    for path in (*OWNERS, *SERVED, *ROBOT, *BRIDGE_HEARS, *BOOKKEEPING):
        contract.topic(path)  # a renamed topic must fail here, not open a hole
    open_keys = [t.pattern_in(namespace) for t in contract.TOPICS
                 if t.path not in OWNERS and t.path not in SERVED]  # fmt: skip
    owned = {path: contract.topic(path).pattern_in(namespace) for path in OWNERS}
    served = {path: contract.topic(path).pattern_in(namespace) for path in SERVED}
    everything = f"{keys.ROOT}/{namespace}/**"
    health, alive = (_own(path, namespace, BRIDGE) for path in BOOKKEEPING)
    rules = [
        _rule("deliver", MESSAGES, [everything], flow="egress"),
        _rule("listen", LISTEN, [everything]),
        _rule("publish open topics", (*PUBLISH, "query"), open_keys),
        _rule("query owned topics", ("query",), list(owned.values())),
        *(_rule(f"publish {path}", PUBLISH, [key]) for path, key in owned.items()),
        *(_rule(f"serve {path}", ("declare_queryable", "reply"), [key]) for path, key in served.items()),
        _rule("request latches", ("query",), list(served.values())),
        _rule("publish the robot", PUBLISH,
              [*(contract.topic(path).pattern_in(namespace) for path in ROBOT), health]),
        _rule("hear safety", ("declare_subscriber",),
              [contract.topic(path).pattern_in(namespace) for path in BRIDGE_HEARS]),
        _rule("announce the bridge", ("liveliness_token",), [alive]),
    ]  # fmt: skip
    identities = sorted({*OWNERS.values(), *SERVED.values(), REQUESTER, BRIDGE})
    subjects = [{"id": MEMBER, "cert_common_names": members()}] + [
        {"id": name, "cert_common_names": [name]} for name in identities]  # fmt: skip
    grants = {MEMBER: ["deliver", "listen", "publish open topics", "query owned topics"],
              REQUESTER: ["request latches"],
              BRIDGE: ["deliver", "publish the robot", "hear safety", "announce the bridge"]}  # fmt: skip
    for path, owner in OWNERS.items():
        grants.setdefault(owner, []).append(f"publish {path}")
    for path, server in SERVED.items():
        grants.setdefault(server, []).append(f"serve {path}")
    policies = [{"id": f"{name} may", "rules": rules_, "subjects": [name]}
                for name, rules_ in grants.items()]  # fmt: skip
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}  # fmt: skip


def _own(path: str, namespace: str, service: str) -> str:
    """Key expression of contract topic `path` for `service` only (any worker)."""
    segments = ("*" if s.startswith("<") and s != "<service>" else s for s in path.split("/"))
    return "/".join((keys.ROOT, namespace, *(service if s == "<service>" else s for s in segments)))


def _rule(rule_id: str, messages: tuple[str, ...], key_exprs: list[str],
          flow: str = "ingress") -> dict[str, object]:  # fmt: skip
    return {"id": rule_id, "messages": list(messages), "flows": [flow],
            "permission": "allow", "key_exprs": key_exprs}  # fmt: skip


def router_config_text(namespace: str = "*") -> str:
    """A router's Zenoh JSON5 config holding the stack's access rules (TLS comes from the
    router's --tls-dir)."""
    header = ("// Generated by `python -m hamnet.security.acl`: the stack's access rules\n"
              "// (docs/security.md). Use with hamnet router --tls-dir D --zenoh-config this.\n")  # fmt: skip
    return header + json.dumps({"access_control": stack_acl(namespace)}, indent=2) + "\n"


if __name__ == "__main__":
    print(router_config_text(), end="")
