"""Playing one batch of episodes to their ends: every environment plays exactly the episode
it was started on (later auto-reset episodes are stepped but not counted, as the trainer's
held-out evaluation does: counting whichever ends first would favour short episodes), the
policy acting with its mean through the safety filter's training profile.

Per episode it keeps the sim's outcome (success, dropped, timeout), what happened to the arm
on the way (`arm_events`), its length and the object's distances from its goal; optionally
HAMnet's modulation embedding at every step (the skills analysis) and the frames of a few
environments (`episode_view`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from hamnet.evaluation.arm_events import ArmEvents, safety_stopped
from hamnet.evaluation.records import EpisodeRecord, failure_reason
from hamnet.evaluation.skills import modulation_embedding
from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command
from hamnet.policy.policy import Policy
from hamnet.sim.termination import Reason, orientation_error, position_error
from hamnet.trainer.collection.rollout_worker import RolloutWorker


@dataclass(frozen=True)
class Labels:
    """What names the counted environments' episodes: suite, object, pair, init per row."""

    suite: list[str]
    object_name: list[str]
    pair: list[int]
    init: list[int]


@dataclass
class Embeddings:
    """Modulation embeddings of the counted steps, with their episode and step."""

    rows: list[np.ndarray] = field(default_factory=list)
    episode: list[np.ndarray] = field(default_factory=list)
    step: list[np.ndarray] = field(default_factory=list)


Frame = Callable[[int, Observation], None]
"""Called with the step index and the observation before each step (a recording)."""


@torch.no_grad()
def play(
    policy: Policy,
    worker: RolloutWorker,
    started: Observation,
    labels: Labels,
    env_transitions: int,
    first_episode: int = 0,
    embeddings: Embeddings | None = None,
    frame: Frame | None = None,
) -> list[EpisodeRecord]:
    """Play the episodes just started (`started`, their first observation) to their ends.

    Args:
        policy: acts with its mean.
        worker: its environments hold the started episodes; the first len(labels.suite)
            are counted.
        labels: names of the counted episodes.
        env_transitions: the schedule counter the safety filter anneals by.
        first_episode: index of the first counted episode in the whole evaluation (the
            embeddings' episode ids).
        embeddings: collects the counted steps' modulation embeddings when given.
        frame: sees every step's observation before it is stepped.
    """
    env, count = worker.env, len(labels.suite)
    worker.start(np.arange(env.num_envs), started)
    events = ArmEvents(env)
    live = np.zeros(env.num_envs, dtype=bool)
    live[:count] = True  # counted episodes not yet ended
    flags = {name: np.zeros(env.num_envs, dtype=bool) for name in ("stop", "hit", "torque")}
    length = np.zeros(env.num_envs, dtype=np.int64)
    start = position_error(started.object_pose[:, :3], started.goal_pose[:, :3])
    records: dict[int, EpisodeRecord] = {}
    while live.any():
        if frame is not None:
            frame(int(length.max()), worker.observation)
        inputs = worker.inputs(policy)
        acted = policy.act(inputs, deterministic=True, generator=worker.generator)
        if embeddings is not None:
            rows = np.flatnonzero(live)
            embeddings.rows.append(modulation_embedding(policy, inputs)[rows].numpy())
            embeddings.episode.append(first_episode + rows)
            embeddings.step.append(length[rows].copy())
        safe = worker.safe(acted.action, env_transitions)
        result = env.step(Command(safe.q_ref, safe.kp, safe.kd, safe.tau_limit))
        flags["stop"] |= live & safety_stopped(safe)
        flags["hit"][live] |= events.collided(np.flatnonzero(live))
        flags["torque"] |= live & events.torque_limited(safe.tau_limit)
        length += live
        worker.seat.end(acted.action, acted.memory)
        ended = live & (result.terminated | result.truncated)
        final = result.final_observation
        for i in np.flatnonzero(ended):
            records[i] = EpisodeRecord(
                suite=labels.suite[i],
                object_name=labels.object_name[i],
                pair=labels.pair[i],
                init=labels.init[i],
                success=bool(result.success[i]),
                reason=failure_reason(
                    bool(result.success[i]),
                    bool(result.reason[i] == Reason.DROPPED),
                    bool(flags["stop"][i]),
                    bool(flags["hit"][i]),
                    bool(flags["torque"][i]),
                ),
                length=int(length[i]),
                start_distance=float(start[i]),
                final_distance=float(
                    position_error(final.object_pose[i, :3], final.goal_pose[i, :3])
                ),
                final_angle=float(
                    orientation_error(final.object_pose[i, 3:], final.goal_pose[i, 3:])
                ),
            )
        live &= ~ended
        worker.start(result.reset_ids, result.observation)
    return [records[i] for i in range(count)]
