"""Success rate of a policy acting with its mean (no exploration noise) on held-out seeds:
the figure a learning result reports (`final_success_rate`), with the mean goal-reaching
return of the same episodes (`final_goal_return`): the shaping term's episode sum is
lambda_r (phi(s_T) - phi(s_0)), positive when the object ends nearer its goal than it
started, 0 when it never moves, so it shows pushing long before successes do. Each
episode's object-goal distance at its start and its end say the same in metres, and how
many episodes would pass a tighter threshold than the stage's.

The episodes are drawn from the same stage as training but from another seed, so no scene,
object or start of the evaluation was seen in training. Every environment plays exactly one
episode, its first, to its end: counting whichever episodes end first would favour the short
ones, and successes are short.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from hamnet.messages.robot_state import Observation
from hamnet.perception.config import CloudConfig
from hamnet.policy.observation import PoseNoiseConfig
from hamnet.policy.policy import Policy
from hamnet.policy.registry import architecture
from hamnet.sim.env import StepResult
from hamnet.task.rewards import REWARD_NAMES
from hamnet.trainer.collection.rollout_worker import RolloutWorker
from hamnet.trainer.collection.sources import build_workers, frozen_encoder
from hamnet.trainer.runners.run_config import RunConfig

HELD_OUT_SEED_OFFSET = 1_000_003
"""Added to the training seed for evaluation environments (a prime, far from any run seed)."""


@dataclass(frozen=True)
class HeldOut:
    """How the policy's mean did on held-out episodes."""

    success_rate: float
    goal_return: float
    """Mean episode sum of the goal-reaching reward term."""
    start_distance: np.ndarray
    """(episodes,) object-goal distance of each episode's first state, m."""
    final_distance: np.ndarray
    """(episodes,) object-goal distance of each episode's last state, m."""

    def within(self, radius: float) -> float:
        """Share of the episodes whose object ended within `radius` of its goal, m."""
        return float((self.final_distance <= radius).mean())


def success_rate(policy: Policy, config: RunConfig, episodes: int, env_transitions: int) -> float:
    """Fraction of `episodes` held-out episodes (one per environment) that succeeded."""
    return evaluate(policy, config, episodes, env_transitions).success_rate


@torch.no_grad()
def evaluate(
    policy: Policy,
    config: RunConfig,
    episodes: int,
    env_transitions: int,
    clouds: CloudConfig | None = None,
    pose_noise: PoseNoiseConfig | None = None,
    edit: Callable[[Observation], None] | None = None,
) -> HeldOut:
    """Success rate and goal return of `episodes` held-out episodes, one per environment.

    Args:
        policy: acts deterministically (the mean of its Gaussian).
        config: the run whose stage to use; its seed is offset (held out), its encoder is
            the run's (a random one drawn from the run's own seed).
        episodes: how many episodes, one per environment.
        env_transitions: the schedule counter of the policy (safety's xi annealing).
        clouds: how perception samples clouds (default: every surface; a DAgger student
            sees them as the cameras do).
        pose_noise: the error of a student's object pose estimate (default: the worker's,
            as it was trained; zero stds measure what the estimate's error costs).
        edit: changes each observation in place before the policy reads it (a measurement
            of what an input is worth, e.g. a teacher's privileged block replaced).
    """
    acting = dataclasses.replace(
        config,
        architecture=policy.architecture,
        action_space=policy.config.action_space,
        pose_readings=policy.config.pose_readings,
    )
    worker = held_out_worker(acting, episodes, clouds)
    if pose_noise is not None:
        worker.pose_noise = pose_noise
    edit = edit or (lambda observation: None)
    edit(worker.observation)
    policy.eval()

    def step() -> StepResult:
        pending = worker.act(policy, env_transitions, deterministic=True)
        result = worker.env.step(pending.command)
        edit(result.observation)
        worker.observe(policy, pending, result)
        return result

    return play_held_out(worker.observation, step)


def held_out_worker(
    config: RunConfig, episodes: int, clouds: CloudConfig | None = None
) -> RolloutWorker:
    """`episodes` environments of `config`'s stage on the held-out seed (the run's seed
    offset), with perception as `config.architecture` reads it (`clouds`) on the run's
    frozen encoder, and the training profile's filter."""
    sim = dataclasses.replace(
        config.sim, seed=config.seed + HELD_OUT_SEED_OFFSET, num_envs=episodes
    )
    held_out = dataclasses.replace(config, sim=sim)
    encoder = frozen_encoder(config) if architecture(config.architecture).config.clouds else None
    (worker,), _ = build_workers(held_out, groups=1, clouds=clouds, encoder=encoder)
    return worker


def play_held_out(first: Observation, step: Callable[[], StepResult]) -> HeldOut:
    """Play each environment's first episode, from its `first` observation, to its end by
    calling `step` (one step of every environment); the books of those episodes only."""
    episodes = len(first.episode_ids)
    ended = np.zeros(episodes, dtype=bool)
    succeeded = np.zeros(episodes, dtype=bool)
    goal = np.zeros(episodes)
    final = np.zeros(episodes)
    column = REWARD_NAMES.index("goal")
    while not ended.all():
        result = step()
        goal += np.where(ended, 0.0, result.reward_terms[:, column])  # the first episodes only
        dones = result.terminated | result.truncated
        first_end = dones & ~ended  # (B,) episodes ending for the first time
        succeeded |= first_end & result.success
        final[first_end] = _distance(result.final_observation)[first_end]
        ended |= dones
    return HeldOut(float(succeeded.mean()), float(goal.mean()), _distance(first), final)


def _distance(observation: Observation) -> np.ndarray:
    """(B,) distance of each object's centre from its goal position, m."""
    return np.linalg.norm(observation.object_pose[:, :3] - observation.goal_pose[:, :3], axis=1)
