"""The topic contract: every key expression of the stack, its message type, who publishes
it and who reads it.

This table is the single source of `hamnet topics`, of the typed decoding used by tools
that listen to everything (echo, monitor, recorder), of the random-payload tests and of the
secure stack's access rules (`hamnet.security.acl`: exactly the identities named here may
publish, or read, each key). Keys are `hamnet/<ns>/<path>`, where `<path>` holds
placeholders such as `<w>` (worker). Publishers and readers are identities: the `hamnet`
command a process runs (the common name of its certificate in a secure stack), or
`operator`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache

from google.protobuf.message import Message

from hamnet.proto import (
    camera_pb2,
    health_pb2,
    perception_pb2,
    policy_pb2,
    safety_pb2,
    sim_pb2,
    trainer_pb2,
)
from hamnet.runtime import keys

_PLACEHOLDER = re.compile(r"<(\w+)>")


@dataclass(frozen=True)
class Topic:
    """One entry of the contract."""

    path: str
    """Key after `hamnet/<ns>/`, with placeholders: `sim/<w>/state`."""
    message: type[Message] | None
    """Protobuf message class carried on the key; None for liveliness tokens and queryables."""
    publishers: tuple[str, ...]
    """Identities that publish it (a queryable: serve it; a liveliness token: declare it).
    On a key with a `<service>` segment each may publish only under its own name."""
    readers: tuple[str, ...]
    """Identities that subscribe to it (a queryable: ask it; a liveliness token: watch it)."""
    when: str
    """When it is published."""
    note: str = ""
    """When (or which of) the publishers publish it, if not always: `--algo dagger`."""
    finite: bool = True
    """Whether every floating-point tensor must be finite (receivers drop it otherwise)."""
    queryable: bool = False
    """Served by a Zenoh queryable (asked with `get`, answered in JSON text), not published."""
    lossless: bool = False
    """Publishers block instead of dropping when the link is congested: large messages that
    must arrive (weights, rollouts, and scenes: perception answers no state of an episode
    whose scene it lacks, so a dropped scene stalled the closed loop for minutes while a
    trainer's update loaded the cores). Control topics drop: a late state or command is stale.
    (With eclipse-zenoh 1.10.2 a 13 MB put under congestion control `drop` was lost while
    another client flooded the router.)"""
    catch_up: bool = False
    """Its publishers also answer queries with the latest value, so that a reader that
    starts late asks instead of waiting (`Inbox.catch_up`): its readers may query it."""

    @property
    def publisher(self) -> str:
        """Who publishes it, in words (`hamnet topics`): `sim or bridge`."""
        who = (
            "every service, under its own name"
            if "service" in self.placeholders
            else " or ".join(self.publishers)
        )
        return f"{who} ({self.note})" if self.note else who

    @property
    def template(self) -> str:
        """Human-readable key with placeholders, as documented."""
        return f"{keys.ROOT}/<ns>/{self.path}"

    @property
    def pattern(self) -> str:
        """Key expression matching this topic in any namespace."""
        return self.pattern_in("*")

    def pattern_in(self, namespace: str) -> str:
        """Key expression matching every key of this topic in `namespace` ('*' for any)."""
        if namespace != "*":
            keys.check_segment("namespace", namespace)
        return f"{keys.ROOT}/{namespace}/{_PLACEHOLDER.sub('*', self.path)}"

    @property
    def placeholders(self) -> tuple[str, ...]:
        """Names of the placeholders in `path`, e.g. ('w',)."""
        return tuple(_PLACEHOLDER.findall(self.path))

    @property
    def type_name(self) -> str:
        """Fully qualified protobuf type, e.g. `hamnet.RobotState`, `queryable` or
        `liveliness`."""
        if self.message is not None:
            return self.message.DESCRIPTOR.full_name
        return "queryable" if self.queryable else "liveliness"

    def key(self, namespace: str, **fields: str) -> str:
        """Concrete key of this topic: `topic.key("default", w="0")`."""
        missing = set(self.placeholders) - set(fields)
        if missing:
            raise ValueError(f"key {self.template} needs {sorted(missing)}")
        keys.check_segment("namespace", namespace)
        for name, value in fields.items():
            keys.check_segment(name, value)
        path = _PLACEHOLDER.sub(lambda m: fields[m.group(1)], self.path)
        return f"{keys.ROOT}/{namespace}/{path}"

    def matches(self, key: str) -> bool:
        """Whether a concrete key belongs to this topic."""
        parts, expected = key.split("/"), self.pattern.split("/")
        return len(parts) == len(expected) and all(
            e == "*" or p == e for p, e in zip(parts, expected, strict=True)
        )


OPERATOR = "operator"
"""The identity of the people at the stack and their tools: the one that may ask the
latches (safety's e-stop, the bridge's reset)."""

OBSERVERS: tuple[str, ...] = ("echo", "record")
"""Identities that read every key of the stack (`hamnet/<ns>/**`): `hamnet echo` and the
recorder. Every topic that carries messages names them among its readers."""

SERVICES: tuple[str, ...] = (
    "sim",
    "bridge",
    "camera",
    "perception",
    "policy",
    "safety",
    "trainer",
    "rollout",
    "monitor",
    "record",
    "replay",
    "echo",
    "up",
    "router",
)
"""Every command that runs a `hamnet.runtime.service.Service`: each reports its health and
declares its liveliness token under its own name."""


def _read(*names: str) -> tuple[str, ...]:
    """Readers of a topic that carries messages: `names`, and the observers."""
    return (*names, *OBSERVERS)


TOPICS: tuple[Topic, ...] = (
    Topic(
        "sim/<w>/state",
        sim_pb2.RobotState,
        ("sim", "bridge"),
        _read("perception", "policy", "safety", "camera", "monitor"),
        "every policy step",
    ),
    Topic(
        "sim/<w>/scene",
        sim_pb2.Scene,
        ("sim",),
        _read("perception", "policy", "monitor"),
        "at resets",
        lossless=True,
        catch_up=True,
    ),
    Topic(
        "sim/<w>/transition",
        sim_pb2.Transition,
        ("sim",),
        _read("policy", "monitor"),
        "every policy step",
    ),
    Topic(
        "camera/<w>/frames",
        camera_pb2.DepthFrames,
        ("camera",),
        _read("perception"),
        "every camera frame",
    ),
    Topic(
        "perception/<w>/tokens",
        perception_pb2.PerceptionTokens,
        ("perception",),
        _read("policy", "monitor"),
        "every policy step",
    ),
    Topic(
        "perception/<w>/object_pose",
        perception_pb2.ObjectPoseEstimate,
        ("perception",),
        _read("bridge"),
        "every policy step",
        note="--clouds-from cameras",
    ),
    Topic(
        "policy/<w>/action",
        policy_pb2.PolicyAction,
        ("policy",),
        _read("safety", "monitor"),
        "every policy step",
        finite=False,
    ),
    Topic(
        "safety/<w>/command",
        safety_pb2.SafeCommand,
        ("safety",),
        _read("sim", "bridge"),
        "every policy step",
    ),
    Topic(
        "safety/<w>/event",
        safety_pb2.SafetyEvent,
        ("safety",),
        _read("monitor"),
        "when a stage clips, rejects or stops",
    ),
    Topic(
        "safety/<w>/estop",
        None,
        ("safety",),
        (OPERATOR,),
        "queryable: stop, reset, status",
        queryable=True,
    ),
    Topic(
        "bridge/<w>/event",
        safety_pb2.SafetyEvent,
        ("bridge",),
        _read(),
        "when the robot raises an error or is reset",
    ),
    Topic(
        "bridge/<w>/reset",
        None,
        ("bridge",),
        (OPERATOR,),
        "queryable: stop, reset, status",
        queryable=True,
    ),
    Topic(
        "trainer/weights",
        trainer_pb2.WeightsAnnouncement,
        ("trainer",),
        _read("policy", "rollout"),
        "after each update",
        lossless=True,
        catch_up=True,
    ),
    Topic(
        "trainer/schedule",
        trainer_pb2.Schedule,
        ("trainer",),
        _read("sim", "policy", "safety"),
        "after each update",
    ),
    Topic(
        "trainer/metrics", trainer_pb2.Metrics, ("trainer",), _read("monitor"), "after each update"
    ),
    Topic(
        "trainer/<w>/rollout",
        trainer_pb2.RolloutChunk,
        ("rollout", "policy"),
        _read("trainer"),
        "every rollout",
        note="the policy in a service chain",
        lossless=True,
    ),
    Topic(
        "trainer/<w>/demonstrations",
        trainer_pb2.RolloutChunk,
        ("rollout",),
        _read("trainer"),
        "every rollout",
        note="--algo dagger",
        lossless=True,
    ),
    Topic("health/<service>/<w>", health_pb2.Health, SERVICES, _read("up"), "every second"),
    Topic("alive/<service>/<w>", None, SERVICES, ("up", "trainer"), "while running"),
)
"""Every topic of the stack.

The real-robot bridge publishes the robot's state under the same `sim/<w>/state` key (it
has no scene and no rewards: no scene, no transition): the segment names the role in the
stack (the robot's executor), so swapping sim for bridge changes nothing for the services
downstream. The policy's raw action may be non-finite: the
safety service, not the transport, rejects it, so that the rejection becomes a safety
event. Publishers and readers are what the code does: a service with ports
(`hamnet.runtime.ports`) publishes its outputs and reads its inputs (serves its queryable
inputs), and a test keeps the two equal; `hamnet replay` publishes only what it recorded,
so it is no publisher of any topic here (docs/security.md)."""

MESSAGE_TOPICS: tuple[Topic, ...] = tuple(t for t in TOPICS if t.message is not None)
"""The topics that carry protobuf messages (all but liveliness tokens and queryables)."""


def topic(path: str) -> Topic:
    """The contract entry with this path template, e.g. `topic("sim/<w>/state")`."""
    for entry in TOPICS:
        if entry.path == path:
            return entry
    raise KeyError(f"no topic {path!r} in the contract; see `hamnet topics`")


@lru_cache(maxsize=4096)
def match_key(key: str) -> Topic | None:
    """The contract entry a concrete key belongs to, or None for keys outside the contract.

    Cached: a stack uses a few dozen keys, and tools that listen to everything look one up
    for every message."""
    return next((entry for entry in TOPICS if entry.matches(key)), None)
