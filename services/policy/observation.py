"""Observation assembly: robot state, the previous action and (for the teacher) the
privileged block to the network's non-geometric inputs, named and sized by one
`ObservationSpec`. Pure, batched torch, shared by the policy service and the trainer.

Poses reach the network as translation + 6D rotation (the first two columns of the
rotation matrix, Zhou et al. 2019; paper line 237). The goal is relative to the object
pose (paper line 237; the authors' RelGoal wrapper, ham/scripts/env_wrappers.py:1056): the
true pose for the teacher, the pose estimator's for the student (paper line 462:
FoundationPose on the real robot; `estimated_pose` is its training-time stand-in).
Shapes: B environments, J joints, A action components.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from hamnet.fr3.limits import ACTION_DIM, NUM_JOINTS
from hamnet.task.physics import PHYSICS_PARAM_NAMES

POSE_WIDTH = 9
"""Translation (3) + 6D rotation (6)."""
VELOCITY_WIDTH = 6
"""Object linear (3, m/s) + angular (3, rad/s) velocity, world frame."""


@dataclass(frozen=True)
class ObservationSpec:
    """Every named input piece and its width, and which pieces feed which part of the
    network. The piece names and orders are the authors' (rss_train.yaml:280-313)."""

    privileged: bool = True
    """Teacher (object pose and velocity, physics parameters) or student (no privileged
    inputs; the object pose is the estimator's)."""
    num_joints: int = NUM_JOINTS
    """J of robot_state = (q, dq)."""
    action_dim: int = ACTION_DIM
    """A of previous_action (the raw action of the last step, zeros at an episode start)."""
    physics_params: int = len(PHYSICS_PARAM_NAMES)
    """Width of the sim's physics parameters (teacher only)."""

    context: tuple[str, ...] = (
        "physics_params",
        "object_state",
        "goal",
        "previous_action",
        "hand_state",
        "robot_state",
    )
    """Non-geometric inputs of the modulation network, in the authors' key_ctx order
    (rss_train.yaml:280-289, after the three clouds); pieces a student lacks are skipped."""
    base: tuple[str, ...] = ("object_state", "goal", "previous_action", "hand_state", "robot_state")
    """Non-geometric inputs of the base network (key_state, rss_train.yaml:300-306)."""
    scene_query: tuple[str, ...] = ("robot_state", "object_state")
    """Query of the local and global scene cross-attentions (cross_big: robot state and
    key_local_cross = object_state, hypernet_modular.py:511, 852-855, 875-878)."""
    object_query: tuple[str, ...] = ("object_state", "goal", "hand_state")
    """Query of the object cross-attention (key_cross_task, hypernet_modular.py:515-516)."""

    @property
    def pieces(self) -> dict[str, int]:
        """Name -> width of every piece this observation has."""
        pieces = {
            "robot_state": 2 * self.num_joints,  # q (rad), dq (rad/s)
            "hand_state": POSE_WIDTH,  # end-effector pose
            "object_state": POSE_WIDTH + VELOCITY_WIDTH if self.privileged else POSE_WIDTH,
            "goal": POSE_WIDTH,  # relative to the (estimated) object pose
            "previous_action": self.action_dim,
        }
        if self.privileged:
            pieces["physics_params"] = self.physics_params
        return pieces

    def names(self, group: str) -> tuple[str, ...]:
        """The pieces of `group` (context, base, scene_query, object_query) this spec has."""
        return tuple(name for name in getattr(self, group) if name in self.pieces)

    def columns(self, group: str, piece: str) -> slice:
        """Where `piece` lies among the columns of `group`."""
        names = self.names(group)
        if piece not in names:
            raise ValueError(f"{group} has no {piece} (it has {', '.join(names)})")
        start = sum(self.pieces[name] for name in names[: names.index(piece)])
        return slice(start, start + self.pieces[piece])

    def width(self, group: str) -> int:
        """Width of `group`'s concatenated pieces."""
        return sum(self.pieces[name] for name in self.names(group))


@dataclass(frozen=True)
class RobotObservation:
    """What the sim (or the real robot's bridge) publishes every policy step, as tensors."""

    q: Tensor
    """(B, J) joint positions, rad."""
    dq: Tensor
    """(B, J) joint velocities, rad/s."""
    ee_pos_rot6d: Tensor
    """(B, 9) end-effector translation (m) + 6D rotation."""
    goal_pose: Tensor
    """(B, 7) goal pose of the object: position (m) + quaternion wxyz."""
    object_pose: Tensor | None = None
    """(B, 7) object position + quaternion wxyz: the true pose (teacher) or the pose
    estimator's (student)."""
    object_velocity: Tensor | None = None
    """(B, 6) object linear (m/s) + angular (rad/s) velocity, world frame; privileged."""
    physics_params: Tensor | None = None
    """(B, P) physics parameters (PHYSICS_PARAM_NAMES); privileged."""


@dataclass(frozen=True)
class NetworkInputs:
    """The network's non-geometric inputs, one tensor per group of `ObservationSpec`."""

    context: Tensor
    """(B, spec.width("context")) modulation-network state."""
    base: Tensor
    """(B, spec.width("base")) base-network state."""
    scene_query: Tensor
    """(B, spec.width("scene_query")) query of the scene cross-attentions."""
    object_query: Tensor
    """(B, spec.width("object_query")) query of the object cross-attention."""


@dataclass(frozen=True)
class PoseNoiseConfig:
    """Error model of the student's object pose in training (docs/policy.md): independent
    every step, as FoundationPose re-estimates every frame (paper line 462)."""

    position_std: float = 0.01
    """Std of the Gaussian position error per axis, m."""
    rotation_std: float = 0.075
    """Std of the Gaussian rotation-vector error per axis, rad."""

    def __post_init__(self) -> None:
        if self.position_std < 0 or self.rotation_std < 0:
            raise ValueError("pose noise stds must be >= 0")


def rotation_matrix(quat: Tensor) -> Tensor:
    """(..., 3, 3) rotation matrices of (..., 4) wxyz quaternions (normalised first)."""
    w, x, y, z = torch.unbind(quat / quat.norm(dim=-1, keepdim=True), dim=-1)
    return torch.stack(
        (
            1 - 2 * (y * y + z * z),
            2 * (x * y - w * z),
            2 * (x * z + w * y),
            2 * (x * y + w * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - w * x),
            2 * (x * z - w * y),
            2 * (y * z + w * x),
            1 - 2 * (x * x + y * y),
        ),
        dim=-1,
    ).reshape(*quat.shape[:-1], 3, 3)


def quaternion_multiply(a: Tensor, b: Tensor) -> Tensor:
    """(..., 4) wxyz Hamilton product a * b (rotate by b, then by a)."""
    aw, ax, ay, az = torch.unbind(a, dim=-1)
    bw, bx, by, bz = torch.unbind(b, dim=-1)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        dim=-1,
    )


def six_d(rotation: Tensor) -> Tensor:
    """(..., 6): the first two columns of (..., 3, 3) rotation matrices, column after column."""
    return rotation[..., :, :2].transpose(-1, -2).reshape(*rotation.shape[:-2], 6)


def pose_9d(pose: Tensor) -> Tensor:
    """(B, 9) translation + 6D rotation of (B, 7) position + wxyz poses."""
    return torch.cat((pose[..., :3], six_d(rotation_matrix(pose[..., 3:]))), dim=-1)


def relative_goal(object_pose: Tensor, goal_pose: Tensor) -> Tensor:
    """(B, 9) goal relative to the object: world-frame offset (3) + 6D of R_goal R_object^T."""
    rotation = rotation_matrix(goal_pose[..., 3:]) @ rotation_matrix(object_pose[..., 3:]).mT
    return torch.cat((goal_pose[..., :3] - object_pose[..., :3], six_d(rotation)), dim=-1)


def estimated_pose(
    pose: Tensor, noise: PoseNoiseConfig, generator: torch.Generator | None
) -> Tensor:
    """(B, 7) a pose estimator's reading of the true (B, 7) poses: Gaussian position error
    and a rotation by a Gaussian rotation vector, applied in the world frame."""
    b = pose.shape[0]
    shape = (b, 3)
    position = torch.randn(shape, generator=generator, device=pose.device) * noise.position_std
    rotvec = torch.randn(shape, generator=generator, device=pose.device) * noise.rotation_std
    angle = rotvec.norm(dim=-1, keepdim=True)  # (B, 1) rad
    axis = rotvec / angle.clamp_min(1e-12)
    error = torch.cat((torch.cos(angle / 2), axis * torch.sin(angle / 2)), dim=-1)  # (B, 4)
    return torch.cat((pose[:, :3] + position, quaternion_multiply(error, pose[:, 3:])), dim=-1)


def _pieces(robot: RobotObservation, previous_action: Tensor, spec: ObservationSpec) -> dict:
    """Name -> (B, width) tensor of every piece of `spec`."""
    if robot.object_pose is None:
        raise ValueError("an observation needs the object pose (true, or the estimator's)")
    pieces = {
        "robot_state": torch.cat((robot.q, robot.dq), dim=-1),  # (B, 2J)
        "hand_state": robot.ee_pos_rot6d,  # (B, 9)
        "object_state": pose_9d(robot.object_pose),  # (B, 9)
        "goal": relative_goal(robot.object_pose, robot.goal_pose),  # (B, 9)
        "previous_action": previous_action,  # (B, A)
    }
    if spec.privileged:
        if robot.object_velocity is None or robot.physics_params is None:
            raise ValueError(
                "a teacher observation needs the privileged block (object "
                "velocity, physics parameters)"
            )
        pieces["object_state"] = torch.cat((pieces["object_state"], robot.object_velocity), -1)
        pieces["physics_params"] = robot.physics_params  # (B, P)
    for name, width in spec.pieces.items():
        if pieces[name].shape[-1] != width:
            raise ValueError(f"{name} has width {pieces[name].shape[-1]}, the spec says {width}")
    return pieces


def assemble(
    robot: RobotObservation, previous_action: Tensor, spec: ObservationSpec
) -> NetworkInputs:
    """The network inputs of one batch of robot states.

    Args:
        robot: the sim's (or the bridge's) state; a student reads only the object pose
            (the estimator's) of the privileged fields.
        previous_action: (B, A) raw action of the previous step, zeros at episode starts.
        spec: which pieces, in which groups.

    Raises:
        ValueError: a missing input the spec needs, or a piece of the wrong width.
    """
    pieces = _pieces(robot, previous_action, spec)
    group = lambda name: torch.cat([pieces[n] for n in spec.names(name)], dim=-1)
    return NetworkInputs(
        group("context"), group("base"), group("scene_query"), group("object_query")
    )
