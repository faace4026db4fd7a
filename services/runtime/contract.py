"""The topic contract: every key expression of the stack, its message type and publisher.

This table is the single source of `hamnet topics`, of the typed decoding used by tools
that listen to everything (echo, monitor, recorder), and of the random-payload tests.
Keys are `hamnet/<ns>/<path>`, where `<path>` holds placeholders such as `<w>` (worker).
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
    publisher: str
    """Who publishes it."""
    when: str
    """When it is published."""
    finite: bool = True
    """Whether every floating-point tensor must be finite (receivers drop it otherwise)."""
    queryable: bool = False
    """Served by a Zenoh queryable (asked with `get`, answered in JSON text), not published."""
    lossless: bool = False
    """Publishers block instead of dropping when the link is congested: large messages that
    must arrive (weights, rollouts). Control topics drop: a late state or command is stale.
    (With eclipse-zenoh 1.10.2 a 13 MB put under congestion control `drop` was lost while
    another client flooded the router.)"""

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


TOPICS: tuple[Topic, ...] = (
    Topic("sim/<w>/state", sim_pb2.RobotState, "sim or bridge", "every policy step"),
    Topic("sim/<w>/scene", sim_pb2.Scene, "sim or bridge", "at resets"),
    Topic("sim/<w>/transition", sim_pb2.Transition, "sim or bridge", "every policy step"),
    Topic("camera/<w>/frames", camera_pb2.DepthFrames, "camera", "every camera frame"),
    Topic("perception/<w>/tokens", perception_pb2.PerceptionTokens, "perception", "every policy step"),
    Topic("perception/<w>/object_pose", perception_pb2.ObjectPoseEstimate, "perception (--clouds-from cameras)",
          "every policy step"),
    Topic("policy/<w>/action", policy_pb2.PolicyAction, "policy", "every policy step", finite=False),
    Topic("safety/<w>/command", safety_pb2.SafeCommand, "safety", "every policy step"),
    Topic("safety/<w>/event", safety_pb2.SafetyEvent, "safety", "when a stage clips, rejects or stops"),
    Topic("safety/<w>/estop", None, "safety", "queryable: stop, reset, status", queryable=True),
    Topic("bridge/<w>/event", safety_pb2.SafetyEvent, "bridge", "when the robot raises an error or is reset"),
    Topic("bridge/<w>/reset", None, "bridge", "queryable: stop, reset, status", queryable=True),
    Topic("trainer/weights", trainer_pb2.WeightsAnnouncement, "trainer", "after each update", lossless=True),
    Topic("trainer/schedule", trainer_pb2.Schedule, "trainer", "after each update"),
    Topic("trainer/metrics", trainer_pb2.Metrics, "trainer", "after each update"),
    Topic("trainer/<w>/rollout", trainer_pb2.RolloutChunk, "rollout worker or policy (service chain)", "every rollout",
          lossless=True),
    Topic("trainer/<w>/demonstrations", trainer_pb2.RolloutChunk, "rollout worker (--algo dagger)", "every rollout",
          lossless=True),
    Topic("health/<service>/<w>", health_pb2.Health, "every service", "every second"),
    Topic("alive/<service>/<w>", None, "every service", "while running"),
)
"""Every topic of the stack.

The real-robot bridge publishes the robot's topics under the same `sim/<w>/...` keys: the
segment names the role in the stack (the robot's executor), so swapping sim for bridge
changes nothing for the services downstream. The policy's raw action may be non-finite: the
safety service, not the transport, rejects it, so that the rejection becomes a safety
event."""

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
