"""Playing one batch of episodes in this process: the policy acts with its mean through the
safety filter of the worker (`hamnet.trainer.collection.rollout_worker.RolloutWorker`), and
`outcomes.Outcomes` keeps the books of every counted episode until each has ended.
Optionally it keeps HAMnet's modulation embedding at every counted step (the skills
analysis) and shows each step to a recording (`episode_view`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from hamnet.evaluation.arm_events import safety_stopped
from hamnet.evaluation.outcomes import Labels, Outcomes
from hamnet.evaluation.records import EpisodeRecord
from hamnet.evaluation.skills import modulation_embedding
from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command
from hamnet.policy.policy import Policy
from hamnet.trainer.collection.rollout_worker import RolloutWorker


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
    env = worker.env
    worker.start(np.arange(env.num_envs), started)
    outcomes = Outcomes(env, started, labels)
    step = 0
    while outcomes.live.any():
        if frame is not None:
            frame(step, worker.observation)
        inputs = worker.inputs(policy)
        acted = policy.act(inputs, deterministic=True, generator=worker.generator)
        if embeddings is not None:
            rows = np.flatnonzero(outcomes.live)
            embeddings.rows.append(modulation_embedding(policy, inputs)[rows].numpy())
            embeddings.episode.append(first_episode + rows)
            embeddings.step.append(outcomes.length[rows].copy())
        safe = worker.safe(acted.action, env_transitions)
        result = env.step(Command(safe.q_ref, safe.kp, safe.kd, safe.tau_limit))
        outcomes.stopped(np.flatnonzero(safety_stopped(safe)))
        outcomes.step(result, safe.tau_limit)
        worker.seat.end(acted.action, acted.memory)
        worker.start(result.reset_ids, result.observation)
        step += 1
    return outcomes.done()
