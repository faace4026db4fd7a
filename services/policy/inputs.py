"""The one input builder of the policy: robot state, tokens and what is carried between
steps (previous action, recurrent memory, EnvCode) to `PolicyInputs`. Pure, batched torch
without Zenoh: the policy service (`hamnet.policy.serving`) calls it per message, a trainer
calls it in-process on `VectorEnv` observations, and both see the same inputs.

A step is `begin_step` (zero the carry of environments whose episode started), then
`observed_state` (a student's pose estimate, averaged over its last readings), then
`policy_inputs`, then `end_step` with what the policy did. The previous action is the raw
action the policy returned (the authors' AddPrevAction stores the action passed to step
and zeroes it at resets, ham/scripts/env_wrappers.py:1040-1053). Shapes: B environments,
A action components, H memory, C EnvCode width, K pose readings kept.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import torch
from torch import Tensor

from hamnet.policy.config import ModelConfig
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import PoseNoiseConfig, RobotObservation, assemble, estimated_pose
from hamnet.policy.policy import Policy


@dataclass(frozen=True)
class Carry:
    """What the builder remembers of every environment between two steps."""

    episode_ids: Tensor
    """(B,) int64 episode of the last step (-1 before the first)."""
    previous_action: Tensor
    """(B, A) raw action of the last step; zeros at an episode start."""
    memory: Tensor | None
    """(B, H) recurrent memory of a student; None for a feed-forward policy."""
    pose_readings: Tensor | None = None
    """(B, K, 7) a student's last K object pose readings, newest last
    (`ModelConfig.pose_readings` > 1); None otherwise."""
    readings_held: Tensor | None = None
    """(B,) int64 how many of `pose_readings` belong to the current episode."""


def robot_observation(observation, device="cpu") -> RobotObservation:
    """The `RobotObservation` of a `hamnet.sim.env.Observation` (numpy, (B, ...) fields of
    the same names): the trainer's in-process path, without the wire."""
    fields = (
        "q",
        "dq",
        "ee_pos_rot6d",
        "goal_pose",
        "object_pose",
        "object_velocity",
        "physics_params",
    )
    return RobotObservation(
        **{
            name: torch.as_tensor(getattr(observation, name), dtype=torch.float32, device=device)
            for name in fields
        }
    )


def initial_carry(policy: Policy, batch: int) -> Carry:
    """The carry of `batch` environments before their first step, on the policy's device."""
    like, kept = policy.log_std, policy.config.pose_readings
    ids = torch.full((batch,), -1, dtype=torch.int64, device=like.device)
    return Carry(
        episode_ids=ids,
        previous_action=like.new_zeros(batch, policy.config.action_dim),
        memory=policy.initial_memory(batch),
        pose_readings=like.new_zeros(batch, kept, 7) if kept > 1 else None,
        readings_held=torch.zeros_like(ids) if kept > 1 else None,
    )


def begin_step(carry: Carry, episode_ids: Tensor, episode_step: Tensor) -> Carry:
    """The carry with the rows of new episodes zeroed.

    Args:
        episode_ids: (B,) int64 episode of every environment at this step.
        episode_step: (B,) policy steps since each episode started (0 at its first).
    """
    if len(episode_ids) != len(carry.episode_ids):
        raise ValueError(
            f"carry of {len(carry.episode_ids)} environments, step of {len(episode_ids)}"
        )
    keep = ((episode_step != 0) & (episode_ids == carry.episode_ids)).unsqueeze(1)  # (B, 1)
    memory = None if carry.memory is None else carry.memory * keep
    held = None if carry.readings_held is None else carry.readings_held * keep[:, 0]
    return Carry(episode_ids, carry.previous_action * keep, memory, carry.pose_readings, held)


def end_step(carry: Carry, action: Tensor, memory: Tensor | None) -> Carry:
    """The carry after the policy acted: its raw action (B, A) and next memory (B, H)."""
    return dataclasses.replace(
        carry,
        previous_action=action.detach(),
        memory=None if memory is None else memory.detach(),
    )


def observed_state(
    config: ModelConfig,
    carry: Carry,
    robot: RobotObservation,
    pose_noise: PoseNoiseConfig | None = None,
    generator: torch.Generator | None = None,
) -> tuple[Carry, RobotObservation]:
    """The state as the policy reads it, and the carry holding this step's pose reading.

    A teacher reads `robot` as it is. A student reads the object pose as its estimator
    does: the simulator's true pose with `pose_noise` (a new error every step), or a real
    estimator's (`pose_noise` None); with `config.pose_readings` K > 1, the mean of the last
    K readings of its episode: positions averaged, quaternions taken on the newest's
    hemisphere, averaged and normalised. The mean lags a moving object by (K - 1) / 2
    steps and cuts the error's spread by sqrt(K).

    Args:
        carry: after `begin_step` of this step.
        robot: the state, `object_pose` true (simulator) or estimated (real robot).
        pose_noise: the estimator's error model, for a student in the simulator.
        generator: of the pose noise.
    """
    if config.privileged or robot.object_pose is None:
        return carry, robot
    reading = robot.object_pose
    if pose_noise is not None:
        reading = estimated_pose(reading, pose_noise, generator)
    if carry.pose_readings is not None:
        readings = torch.cat((carry.pose_readings[:, 1:], reading[:, None]), dim=1)  # (B, K, 7)
        held = (carry.readings_held + 1).clamp_max(readings.shape[1])  # (B,)
        carry = dataclasses.replace(carry, pose_readings=readings, readings_held=held)
        reading = mean_pose(readings, held)
    return carry, RobotObservation(robot.q, robot.dq, robot.ee_pos_rot6d, robot.goal_pose, reading)


def mean_pose(readings: Tensor, held: Tensor) -> Tensor:
    """(B, 7) mean of the newest `held` (B,) of `readings` (B, K, 7), oldest first: positions
    averaged, quaternions flipped onto the newest's hemisphere, averaged, normalised."""
    kept = readings.shape[1]
    back = torch.arange(kept - 1, -1, -1, device=readings.device)  # (K,) steps before newest
    weight = (back[None, :] < held[:, None]).to(readings.dtype)[..., None]  # (B, K, 1)
    newest = readings[:, -1:, 3:]  # (B, 1, 4)
    side = torch.where((readings[..., 3:] * newest).sum(-1, keepdim=True) < 0, -1.0, 1.0)
    aligned = torch.cat((readings[..., :3], readings[..., 3:] * side), dim=-1)
    mean = (weight * aligned).sum(1) / weight.sum(1)  # (B, 7)
    return torch.cat((mean[:, :3], torch.nn.functional.normalize(mean[:, 3:], dim=-1)), -1)


def store_env_code(cache: Tensor, env_ids: Tensor, env_code: Tensor) -> Tensor:
    """The EnvCode cache (E, C) with rows `env_ids` (K,) set to `env_code` (K, C); it grows
    to cover the largest id (scenes arrive only for environments that were reset)."""
    rows = max(len(cache), int(env_ids.max()) + 1 if len(env_ids) else 0)
    grown = cache.new_zeros(rows, cache.shape[1])
    grown[: len(cache)] = cache
    grown[env_ids] = env_code.to(grown)
    return grown


def policy_inputs(
    config: ModelConfig,
    carry: Carry,
    robot: RobotObservation,
    tokens: tuple[Tensor, Tensor, Tensor],
    env_code: Tensor | None = None,
) -> PolicyInputs:
    """The network inputs of one step.

    Args:
        config: the policy's architecture.
        carry: after `observed_state` of this step.
        robot: the state as the policy reads it (`observed_state`).
        tokens: object, local and global tokens, (B, N, D) each.
        env_code: (>= B, C) EnvCode cache, for the EnvCode oracle only.
    """
    b = len(robot.q)
    code = None
    if config.scene_input == "env_code":
        if env_code is None or len(env_code) < b:
            raise ValueError(f"the EnvCode oracle needs the EnvCode of all {b} environments")
        code = env_code[:b]
    obj, local, whole = tokens
    return PolicyInputs(
        observation=assemble(robot, carry.previous_action, config.observation),
        object_tokens=obj,
        local_tokens=local,
        global_tokens=whole,
        env_code=code,
        memory=carry.memory,
    )
