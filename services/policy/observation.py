"""Observation assembly: robot state (and, for the teacher, the privileged block) to the
network's non-geometric inputs. One pure, batched torch function shared by the policy
service and the trainer, so both see exactly the same observation.

Poses reach the network as translation + 6D rotation (the first two columns of the
rotation matrix, Zhou et al. 2019; paper line 237). The goal is relative to the current
object pose for the teacher (paper line 237); the student cannot observe the object pose,
so it gets the goal in the world frame and infers the object from its cloud tokens.
Shapes: B environments.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

POSE_WIDTH = 9
"""Translation (3) + 6D rotation (6)."""


@dataclass(frozen=True)
class RobotObservation:
    """What the sim publishes every policy step, as float32 tensors."""

    q: Tensor
    """(B, 7) joint positions, rad."""
    dq: Tensor
    """(B, 7) joint velocities, rad/s."""
    ee_pose: Tensor
    """(B, 9) end-effector translation (m) + 6D rotation."""
    goal_pose: Tensor
    """(B, 7) goal pose of the object: position (m) + quaternion wxyz."""
    object_pose: Tensor | None = None
    """(B, 7) object position + quaternion wxyz; privileged (None on the real robot)."""
    object_velocity: Tensor | None = None
    """(B, 6) object linear (m/s) + angular (rad/s) velocity; privileged."""
    physics_params: Tensor | None = None
    """(B, 6) mass, frictions, restitution, scale; privileged."""


@dataclass(frozen=True)
class Observation:
    """The network's non-geometric inputs (the paper's input groups 1-3, Fig. overall-arch)."""

    state: Tensor
    """(B, S) group 3, every non-geometric input: S = 53 teacher, 32 student."""
    scene_query: Tensor
    """(B, Q1) group 1, robot and object state that query the scene tokens: 32 / 23."""
    object_query: Tensor
    """(B, Q2) group 2, hand and goal that query the object tokens: 18."""


def widths(privileged: bool) -> tuple[int, int, int]:
    """(S, Q1, Q2) of `assemble` for a teacher (privileged) or a student."""
    return (53, 32, 18) if privileged else (32, 23, 18)


def rotation_matrix(quat: Tensor) -> Tensor:
    """(..., 3, 3) rotation matrices of (..., 4) wxyz quaternions (normalised first)."""
    w, x, y, z = torch.unbind(quat / quat.norm(dim=-1, keepdim=True), dim=-1)
    return torch.stack(
        (
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ),
        dim=-1,
    ).reshape(*quat.shape[:-1], 3, 3)  # fmt: skip


def six_d(rotation: Tensor) -> Tensor:
    """(..., 6): the first two columns of (..., 3, 3) rotation matrices, column after column."""
    return rotation[..., :, :2].transpose(-1, -2).reshape(*rotation.shape[:-2], 6)


def pose_9d(pose: Tensor) -> Tensor:
    """(B, 9) translation + 6D rotation of (B, 7) position + wxyz poses."""
    return torch.cat((pose[..., :3], six_d(rotation_matrix(pose[..., 3:]))), dim=-1)


def relative_goal(object_pose: Tensor, goal_pose: Tensor) -> Tensor:
    """(B, 9) goal relative to the object: world-frame offset (3) + 6D of R_goal R_object^T."""
    rotation = rotation_matrix(goal_pose[..., 3:]) @ rotation_matrix(object_pose[..., 3:]).transpose(-1, -2)
    return torch.cat((goal_pose[..., :3] - object_pose[..., :3], six_d(rotation)), dim=-1)


def assemble(robot: RobotObservation, privileged: bool) -> Observation:
    """The network inputs of one batch of robot states.

    Args:
        robot: the sim's (or the bridge's) state; the privileged fields are needed only when
            `privileged` is True and ignored otherwise.
        privileged: teacher (True) or student (False) inputs.

    Raises:
        ValueError: a teacher observation without the privileged block.
    """
    joints = torch.cat((robot.q, robot.dq), dim=-1)  # (B, 14) x^q
    if not privileged:
        goal = pose_9d(robot.goal_pose)  # (B, 9) world frame
        return Observation(
            state=torch.cat((joints, robot.ee_pose, goal), dim=-1),  # (B, 14 + 9 + 9 = 32)
            scene_query=torch.cat((joints, robot.ee_pose), dim=-1),  # (B, 14 + 9 = 23)
            object_query=torch.cat((robot.ee_pose, goal), dim=-1),  # (B, 9 + 9 = 18)
        )
    if robot.object_pose is None or robot.object_velocity is None or robot.physics_params is None:
        raise ValueError("a teacher observation needs the privileged block (object pose, "
                         "object velocity, physics parameters)")  # fmt: skip
    obj = pose_9d(robot.object_pose)  # (B, 9)
    goal = relative_goal(robot.object_pose, robot.goal_pose)  # (B, 9)
    state = torch.cat(  # (B, 14 + 9 + 9 + 6 + 6 + 9 = 53)
        (joints, robot.ee_pose, obj, robot.object_velocity, robot.physics_params, goal), dim=-1
    )
    return Observation(
        state=state,
        scene_query=torch.cat((joints, robot.ee_pose, obj), dim=-1),  # (B, 14 + 9 + 9 = 32)
        object_query=torch.cat((robot.ee_pose, goal), dim=-1),  # (B, 9 + 9 = 18)
    )
