"""A scripted pusher: a hand-written closed-loop controller that pushes the object to its goal
through the policy's own action space (a residual joint target and gains, through the safety
filter's training profile), reading the privileged state: the object's and the goal's poses,
the paddle's position and the object's size.

It is the easy stage's reference: what a controller that knows the state gets from the same
arm, action mapping and physics as PPO, on the same held-out episodes
(`hamnet.evaluation.scripted_pusher`, docs/results/scripted-push.json). It plans nothing
around obstacles and reads the true object pose: a measurement, not a policy to deploy. In
training it is PPO's guide (`GuideConfig`): rollout workers label every state acted in with
its action (`ScriptedPusher`), which the update's imitation term pulls the policy's mean
towards while the guide's weight lasts.

The rule, per environment and step (xy in the table's plane):
- the push line runs from the object's centre to its goal; the contact point lies on it,
  the plate's reach along the line (its 12 x 6 cm face as it is turned now) plus `gap`
  behind the object's rearmost point along the line (its bounding box's corners as it lies
  now: an object resting on its side reaches further than its upright planar radius), so
  the plate's edge, not its centre, stops short of the object; it is shifted sideways by
  `k_yaw` times the yaw error (pushing off-centre turns the object back; bounded to 0.6 of
  the box's sideways reach). The yaw error is the rotation about the vertical between the
  goal's orientation and the object's (not the difference of their Euler yaws, which jumps
  by up to pi for an object tilted on its side);
- aligned (the paddle within `align_tolerance` of that shifted line, behind the object):
  the paddle moves along the line by min(`speed`, `slow` x the remaining distance), pulled
  back towards the line by `lateral_gain`; otherwise it moves towards the contact point;
- the paddle's height goes halfway to `lift` above the object's centre each step, and its
  orientation is held (the twist's angular rows are 0).
The motion (at most `max_step` per step in xy) is the action's twist in the paddle space
(u = motion / `twist_linear`); in the joint space it becomes a joint residual by damped least
squares on Pinocchio's paddle Jacobian, and u = residual / xi (the filter's scale, stage 2),
which is what the paddle space's filter does with the twist (its damping added to J J^T is
`twist_damping` squared, 1e-6, where the script adds `damping`, 1e-3: the two residuals
differ by a few percent). The gains are constant (`kp_u`, `rho_u`). The defaults are the best
of sweeps on the easy stage (docs/trainer-history.md, "A scripted reference" and "The
pusher's plate").
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import torch

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.fr3.model import load_pinocchio, paddle_plate_half_extents
from hamnet.messages.robot_state import Observation
from hamnet.safety.cartesian import damped_least_squares, ee_jacobians
from hamnet.safety.config import ActionMagnitudeConfig
from hamnet.safety.schedule import per_joint, xi_at
from hamnet.safety.stages import twist_scale
from hamnet.sim import quaternion
from hamnet.sim.env import VectorEnv
from hamnet.sim.rewards import bbox_corners, to_world

OFFSET_LIMIT = 0.6
"""Largest sideways shift of the contact point, as a share of the object's sideways reach
from its centre (beyond, the paddle slips past the object's side)."""


@dataclass(frozen=True)
class PusherConfig:
    """The pusher's constants (defaults: the best of a sweep on the easy stage)."""

    gap: float = 0.01
    """Distance between the plate's edge and the object's rearmost point at the contact
    point, m (docs/trainer-history.md, "The pusher's plate")."""
    speed: float = 0.02
    """Paddle motion asked per policy step while pushing, m."""
    slow: float = 0.5
    """Near the goal, at most this fraction of the remaining distance per step."""
    lift: float = 0.02
    """Paddle height above the object's centre, m."""
    k_yaw: float = 0.2
    """Sideways shift of the contact point per radian of yaw error, m/rad."""
    lateral_gain: float = 1.5
    """Pull back to the push line per step, as a multiple of half the sideways error."""
    align_tolerance: float = 0.02
    """Sideways distance from the line under which the paddle pushes, m."""
    max_step: float = 0.02
    """Largest xy motion asked per step, m."""
    kp_u: float = 1.0
    """Stiffness action component (1: the filter's kp_max)."""
    rho_u: float = 0.0
    """Damping-ratio action component (0: halfway through the filter's range)."""
    damping: float = 1e-3
    """What the joint space's damped least squares adds to J J^T (lambda^2, m^2)."""


@dataclass(frozen=True)
class PushState:
    """What the pusher reads, for B environments."""

    tip: np.ndarray
    """(B, 3) the paddle's position, m."""
    plate_axes: np.ndarray
    """(B, 2, 3) the plate's x and y axes in the world (the ee frame's first two columns)."""
    object_pose: np.ndarray
    """(B, 7) position and wxyz quaternion."""
    goal_pose: np.ndarray
    """(B, 7) position and wxyz quaternion."""
    corners: np.ndarray
    """(B, 8, 3) the corners of the object's bounding box in the world, m."""
    jacobians: np.ndarray | None = None
    """(B, 6, J) the paddle's world-aligned Jacobian (linear rows, then angular); joint
    space only."""
    xi: np.ndarray | None = None
    """(J,) the filter's residual scale this step, rad; joint space only."""


def yaw_of(quat: np.ndarray) -> np.ndarray:
    """Rotation about the vertical of wxyz quaternions (B, 4), rad."""
    w, x, y, z = quat.T
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def yaw_error(quat: np.ndarray, goal_quat: np.ndarray) -> np.ndarray:
    """(B,) rotation about the vertical from the goal's orientation to the object's, rad in
    [-pi, pi]: the yaw of the world-frame rotation between them, exact when the object rests
    on the goal's face."""
    return yaw_of(quaternion.multiply(quat, quaternion.conjugate(goal_quat)))


def plate_reach(plate_axes: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(B,) how far the plate reaches from its centre along the horizontal unit `direction`
    (B, 2), m: its half extents weighed by how each of its axes (B, 2, 3) lies along it."""
    along = np.abs((plate_axes[:, :, :2] * direction[:, None]).sum(axis=2))  # (B, 2)
    return along @ paddle_plate_half_extents()


def paddle_motion(state: PushState, config: PusherConfig) -> np.ndarray:
    """The paddle's motion asked this step (B, 3), m: along the push line or to its start."""
    pos, goal, tip = state.object_pose[:, :3], state.goal_pose[:, :3], state.tip
    to_goal = goal[:, :2] - pos[:, :2]  # (B, 2)
    remaining = np.linalg.norm(to_goal, axis=1, keepdims=True)  # (B, 1)
    forward = to_goal / np.maximum(remaining, 1e-9)  # (B, 2)
    left = np.stack([-forward[:, 1], forward[:, 0]], axis=1)  # (B, 2)
    turned = yaw_error(state.object_pose[:, 3:], state.goal_pose[:, 3:])  # (B,)
    reach = state.corners[:, :, :2] - pos[:, None, :2]  # (B, 8, 2) corners from the centre
    behind = -(reach * forward[:, None]).sum(axis=2).min(axis=1)  # (B,) rearmost point
    bound = OFFSET_LIMIT * np.abs((reach * left[:, None]).sum(axis=2)).max(axis=1)  # (B,)
    shift = left * np.clip(config.k_yaw * turned, -bound, bound)[:, None]  # (B, 2)
    clearance = behind + plate_reach(state.plate_axes, forward) + config.gap  # (B,)
    contact = pos[:, :2] - forward * clearance[:, None] + shift  # (B, 2)
    relative = tip[:, :2] - pos[:, :2]  # (B, 2)
    along = (relative * forward).sum(axis=1)  # (B,), < 0 behind the object
    sideways = relative - along[:, None] * forward - shift  # (B, 2)
    aligned = (np.linalg.norm(sideways, axis=1) < config.align_tolerance) & (along < 0.0)
    push = (
        forward * np.minimum(config.speed, config.slow * remaining)
        - 0.5 * config.lateral_gain * sideways
    )
    target = np.where(aligned[:, None], tip[:, :2] + push, contact)  # (B, 2)
    xy = target - tip[:, :2]
    norm = np.linalg.norm(xy, axis=1, keepdims=True)
    xy = xy * np.minimum(1.0, config.max_step / np.maximum(norm, 1e-9))
    z = 0.5 * (pos[:, 2] + config.lift - tip[:, 2])  # (B,)
    return np.concatenate([xy, z[:, None]], axis=1)


def push_actions(state: PushState, config: PusherConfig) -> np.ndarray:
    """Raw joint-space actions (B, 21) [u_dq | u_kp | u_rho] that ask the arm for
    `paddle_motion`."""
    b = len(state.tip)
    twist = np.zeros((b, 6))
    twist[:, :3] = paddle_motion(state, config)
    # `damping` is added to J J^T as it is: lambda = its square root
    dq = damped_least_squares(state.jacobians, twist, np.sqrt(config.damping))  # (B, J)
    return with_gains(np.clip(dq / state.xi, -1.0, 1.0), config)


def twist_actions(
    state: PushState, config: PusherConfig, magnitude: ActionMagnitudeConfig
) -> np.ndarray:
    """Raw paddle-space actions (B, 21) [u_twist | 0 | u_kp | u_rho] that ask the paddle for
    `paddle_motion` (its orientation held, the null-space component unused)."""
    u = np.zeros((len(state.tip), NUM_JOINTS))
    u[:, :3] = paddle_motion(state, config) / twist_scale(magnitude)[:3]
    return with_gains(np.clip(u, -1.0, 1.0), config)


def with_gains(u: np.ndarray, config: PusherConfig) -> np.ndarray:
    """(B, 21): the residual components `u` (B, J) followed by the constant gains."""
    b = len(u)
    gains = np.concatenate(
        [np.full((b, NUM_JOINTS), config.kp_u), np.full((b, NUM_JOINTS), config.rho_u)], axis=1
    )
    return np.concatenate([u, gains], axis=1)


class ScriptedPusher:
    """The pusher over the environments of one `VectorEnv`, acting in the action space of
    the filter `magnitude` describes: what a rollout worker labels its states with (PPO's
    guide) and what the held-out reference plays."""

    def __init__(
        self,
        env: VectorEnv,
        magnitude: ActionMagnitudeConfig,
        config: PusherConfig | None = None,
    ) -> None:
        self.env, self.magnitude = env, magnitude
        self.config = config if config is not None else PusherConfig()
        self.corners_of = bbox_corners(env.library.bbox)
        """(N, 8, 3) the object-frame bounding-box corners of every library entry, m."""
        self.model, self.data = load_pinocchio() if magnitude.space == "joint" else (None, None)

    def actions(self, observation: Observation, env_transitions: int) -> torch.Tensor:
        """(B, 21) float32 raw actions for `observation`, the filter at the schedule counter
        `env_transitions` (the joint space's residual scale xi)."""
        pose = observation.object_pose.astype(np.float64)  # (B, 7)
        ee = observation.ee_pos_rot6d.astype(np.float64)  # (B, 9)
        state = PushState(
            tip=ee[:, :3],
            plate_axes=ee[:, 3:].reshape(-1, 2, 3),
            object_pose=pose,
            goal_pose=observation.goal_pose.astype(np.float64),
            corners=to_world(pose[:, :3], pose[:, 3:], self.corners_of[self.env.object_index]),
        )
        if self.magnitude.space == "paddle":
            action = twist_actions(state, self.config, self.magnitude)
        else:
            magnitude = self.magnitude
            xi = per_joint(*xi_at(env_transitions, magnitude), magnitude.num_large_joints)
            jacobians = ee_jacobians(self.model, self.data, observation.q, "full")
            action = push_actions(
                dataclasses.replace(state, jacobians=jacobians, xi=xi), self.config
            )
        return torch.as_tensor(action, dtype=torch.float32)
