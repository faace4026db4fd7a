"""What each counted episode of a batch came to, step after step: the sim's outcome
(success, dropped, timeout), what happened to the arm on the way (`arm_events`), its length
and the object's distances from its goal. Only the episode each environment was started on
counts: later auto-reset episodes are stepped but not counted, as the trainer's held-out
evaluation does (counting whichever ends first would favour short episodes).

In-process (`play`) and over the services (`stack`) keep their books here alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hamnet.evaluation.arm_events import ArmEvents
from hamnet.evaluation.records import EpisodeRecord, failure_reason
from hamnet.messages.robot_state import Observation
from hamnet.sim.env import StepResult, VectorEnv
from hamnet.sim.termination import Reason, orientation_error, position_error


@dataclass(frozen=True)
class Labels:
    """What names the counted environments' episodes: suite, object, pair, init per row."""

    suite: list[str]
    object_name: list[str]
    pair: list[int]
    init: list[int]


class Outcomes:
    """The books of the first len(labels.suite) environments' started episodes."""

    def __init__(self, env: VectorEnv, started: Observation, labels: Labels) -> None:
        self.env, self.labels = env, labels
        self.events = ArmEvents(env)
        self.live = np.zeros(env.num_envs, dtype=bool)
        """(B,) counted episodes not yet ended."""
        self.live[: len(labels.suite)] = True
        self.flags = {
            name: np.zeros(env.num_envs, dtype=bool) for name in ("stop", "hit", "torque")
        }
        self.length = np.zeros(env.num_envs, dtype=np.int64)
        self.start = position_error(started.object_pose[:, :3], started.goal_pose[:, :3])
        self.records: dict[int, EpisodeRecord] = {}

    def stopped(self, env_ids: np.ndarray) -> None:
        """The safety filter stopped following the policy in `env_ids` (K,)."""
        self.flags["stop"][env_ids] |= self.live[env_ids]

    def step(self, result: StepResult, tau_limit: np.ndarray) -> None:
        """Take in a step whose command clipped torques at `tau_limit` (B, J)."""
        live = self.live
        self.flags["hit"][live] |= self.events.collided(np.flatnonzero(live))
        self.flags["torque"] |= live & self.events.torque_limited(tau_limit)
        self.length += live
        ended = live & (result.terminated | result.truncated)
        for i in np.flatnonzero(ended):
            self.records[i] = self._record(i, result)
        self.live = live & ~ended

    def done(self) -> list[EpisodeRecord]:
        """The counted episodes' records, in environment order (all must have ended)."""
        return [self.records[i] for i in range(len(self.labels.suite))]

    def _record(self, i: int, result: StepResult) -> EpisodeRecord:
        final, success = result.final_observation, bool(result.success[i])
        return EpisodeRecord(
            suite=self.labels.suite[i],
            object_name=self.labels.object_name[i],
            pair=self.labels.pair[i],
            init=self.labels.init[i],
            success=success,
            reason=failure_reason(
                success,
                bool(result.reason[i] == Reason.DROPPED),
                bool(self.flags["stop"][i]),
                bool(self.flags["hit"][i]),
                bool(self.flags["torque"][i]),
            ),
            length=int(self.length[i]),
            start_distance=float(self.start[i]),
            final_distance=float(position_error(final.object_pose[i, :3], final.goal_pose[i, :3])),
            final_angle=float(orientation_error(final.object_pose[i, 3:], final.goal_pose[i, 3:])),
        )
