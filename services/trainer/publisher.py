"""What the trainer publishes: versioned weights, the one schedule counter, and metrics.

Produces `trainer/weights` (WeightsAnnouncement: the policy's safetensors bytes with its
architecture, config and SHA-256, which `hamnet policy` hot-reloads), `trainer/schedule`
(Schedule: env_transitions, from which sim, safety and policy compute their schedules) and
`trainer/metrics` (Metrics: one iteration's numbers, drawn by `hamnet monitor`). Weights are
large (about 13 MB for HAMnet), so they go out every `weights_period_s` and at the end;
the counter and metrics after every iteration.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping

from hamnet.messages.schedule import encode as encode_schedule
from hamnet.policy.policy import Policy
from hamnet.policy.weights import sha256, to_bytes
from hamnet.proto.common_pb2 import Header
from hamnet.proto.trainer_pb2 import Metrics, WeightsAnnouncement
from hamnet.runtime import contract
from hamnet.runtime.service import Service

WEIGHTS = contract.topic("trainer/weights")
SCHEDULE = contract.topic("trainer/schedule")
METRICS = contract.topic("trainer/metrics")


def encode_weights(
    policy: Policy, version: int, env_transitions: int, rollout_steps: int = 0
) -> WeightsAnnouncement:
    """WeightsAnnouncement of `policy` as `version` (header.step = the version), acting at
    the schedule counter `env_transitions`, for rollouts of `rollout_steps` steps (0: none
    asked for)."""
    data = to_bytes(policy, version)
    return WeightsAnnouncement(
        header=Header(step=version, policy_version=version),
        version=version,
        architecture=policy.architecture,
        config_json=policy.config.to_json(),
        safetensors=data,
        sha256=sha256(data),
        env_transitions=int(env_transitions),
        rollout_steps=rollout_steps,
    )


def encode_metrics(row: Mapping[str, object], iteration: int) -> Metrics:
    """Metrics of one iteration: every finite number of `row` (flags as 0/1)."""
    message = Metrics(header=Header(step=iteration, policy_version=iteration), iteration=iteration)
    for name, value in row.items():
        if isinstance(value, bool | int | float) and math.isfinite(float(value)):
            message.scalars[name] = float(value)
    return message


class TrainerPublisher:
    """Publishes a run's weights, counter and metrics from its iterations."""

    def __init__(
        self, service: Service, weights_period_s: float = 10.0, rollout_steps: int = 0
    ) -> None:
        """`rollout_steps`: the run's T, which its announcements ask rollout workers to act."""
        ns = service.namespace
        self.rollout_steps = rollout_steps
        self.weights = service.publisher(WEIGHTS.key(ns))
        self.schedule = service.publisher(SCHEDULE.key(ns))
        self.metrics = service.publisher(METRICS.key(ns))
        self.weights_period_s = weights_period_s
        self._last_weights = -math.inf

    def publish(self, policy: Policy, row: Mapping[str, object], final: bool = False) -> None:
        """One iteration's messages; the weights (version: updates + 1) when due (or `final`)."""
        iteration = int(row["iteration"])
        if final or time.monotonic() - self._last_weights >= self.weights_period_s:
            self.weights.put(
                encode_weights(
                    policy, iteration + 1, int(row["env_transitions"]), self.rollout_steps
                )
            )
            self._last_weights = time.monotonic()
        self.schedule.put(encode_schedule(int(row["env_transitions"]), iteration))
        self.metrics.put(encode_metrics(row, iteration))
