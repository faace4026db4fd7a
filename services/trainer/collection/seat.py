"""A seat at the environments: what one policy keeps to read them, step after step.

A rollout worker has one seat (the acting policy); DAgger's has two, the teacher's and the
student's, on the same environments. Each seat has its own perception (its clouds as that
policy was trained or is deployed), its latest percepts and its carry between steps (previous
action, recurrent memory; `hamnet.policy.inputs`). Shapes: B environments.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import Tensor

from hamnet.perception.core import EpisodeScenes, Perception, Percepts
from hamnet.policy import inputs as builder
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import PoseNoiseConfig, RobotObservation
from hamnet.policy.policy import Policy
from hamnet.sim.env import VectorEnv
from hamnet.trainer.runners.snapshots import (
    Arrays,
    Snapshot,
    fields_of,
    nest,
    part,
    tensor_dataclass,
)


def scenes_of(env: VectorEnv, env_ids: np.ndarray) -> EpisodeScenes:
    """Perception's input for the current episodes of `env_ids` (K,)."""
    s = env.scenes(env_ids)
    return EpisodeScenes.from_arrays(
        s.env_ids,
        s.episode_ids,
        s.cuboid_centre,
        s.cuboid_quat,
        s.cuboid_half_extent,
        s.cuboid_active,
        s.object_points,
    )


def tokens_of(percepts: Percepts | None) -> tuple[Tensor | None, Tensor | None, Tensor | None]:
    """Object, local and global tokens; None for a policy without clouds."""
    if percepts is None:
        return None, None, None
    return percepts.object_tokens, percepts.local_tokens, percepts.global_tokens


class Seat:
    """One policy's perception, percepts and carry over B environments."""

    def __init__(self, perception: Perception | None) -> None:
        """`perception`: None for a policy without clouds."""
        self.perception = perception
        self.percepts: Percepts | None = None
        self.carry: builder.Carry | None = None

    def perceive(self, env: VectorEnv, started: np.ndarray, object_pose: Tensor) -> None:
        """Percepts of the current observation; new caches for the episodes `started`."""
        if self.perception is None:
            return
        if len(started):
            self.perception.start_episodes(scenes_of(env, started))
        self.percepts = self.perception.step(object_pose)

    def begin(self, policy: Policy, episode_ids: Tensor, episode_step: Tensor) -> None:
        """Start a step: a first carry for `policy`, zeroed where an episode began."""
        if self.carry is None:
            self.carry = builder.initial_carry(policy, len(episode_ids))
        self.carry = builder.begin_step(self.carry, episode_ids, episode_step)

    def inputs(
        self,
        policy: Policy,
        robot: RobotObservation,
        pose_noise: PoseNoiseConfig,
        generator: torch.Generator,
    ) -> PolicyInputs:
        """`policy`'s inputs of this step (a student's pose estimate drawn from `generator`,
        kept in the carry when the student averages its readings)."""
        self.carry, robot = builder.observed_state(
            policy.config, self.carry, robot, pose_noise, generator
        )
        return builder.policy_inputs(policy.config, self.carry, robot, tokens_of(self.percepts))

    def end(self, action: Tensor, memory: Tensor | None) -> None:
        """End a step with the executed `action` and the policy's new `memory`."""
        self.carry = builder.end_step(self.carry, action, memory)

    def snapshot(self) -> Snapshot:
        """Perception's caches, the percepts and the carry (those that exist)."""
        parts: dict[str, Snapshot] = {}
        if self.perception is not None:
            parts["perception"] = self.perception.snapshot()
            parts["percepts"] = (fields_of(self.percepts), {})
        if self.carry is not None:
            parts["carry"] = (fields_of(self.carry), {})
        return nest(parts)

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from `snapshot` (a seat built from the same config)."""
        if self.perception is not None:
            self.perception.restore(*part(arrays, meta, "perception"))
            self.percepts = tensor_dataclass(Percepts, part(arrays, meta, "percepts")[0])
        self.carry = None
        if "carry" in meta:
            self.carry = tensor_dataclass(builder.Carry, part(arrays, meta, "carry")[0])
