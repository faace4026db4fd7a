"""Where the arm starts an episode: "near" the object or "random" in the joint space.

The curriculum moves from near starts (the paddle within reach of the object, so contact is
found early) to random ones. Both are collision-free: a candidate whose arm touches the
scene or the object is rejected and drawn again, up to a bounded number of rounds, and the
retracted configuration (`RETRACTED`, then home) is the fallback of an environment that
never found one.

"near": damped-least-squares IK, batched over environments, puts the paddle's contact face
at a point beside the object (at its height, a random horizontal direction, `near_gap`
metres beyond its planar radius). "random": uniform within the central part of each joint
range.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from hamnet.fr3 import limits as fr3_limits
from hamnet.fr3 import model as fr3_model
from hamnet.sim import quaternion
from hamnet.sim.physics import BatchPhysics


@dataclass(frozen=True)
class RobotInitConfig:
    """How initial arm configurations are drawn."""

    range_fraction: float = 0.9
    """Random starts and IK stay within this central fraction of each joint range."""
    near_gap: tuple[float, float] = (0.02, 0.08)
    """Distance from the object's planar radius to the paddle's face for near starts, m."""
    near_lift: tuple[float, float] = (0.03, 0.08)
    """Height of the paddle's face above the object's centre for near starts, m: at the
    centre's height the paddle, which hangs below the flange, would dig into the surface."""
    ik_iterations: int = 40
    """Damped-least-squares iterations per near start."""
    ik_damping: float = 0.05
    """Damping of the least squares, m."""
    ik_tolerance: float = 0.03
    """A near start must bring the paddle within this distance of its target, m."""
    ik_seed_spread: float = 0.6
    """The IK starts from home in the first draw, then from home plus N(0, this) per joint,
    rad: from home alone it finds the same arm posture again and again, and when that
    posture's elbow or wrist is in a wall or ceiling every draw fails (fallbacks with every
    start near: 29% from home only, 25% with this spread)."""
    rounds: int = 8
    """Draws per environment before falling back to the home configuration."""
    near_directions: int = 8
    """Directions tried per near draw: the first whose target leaves room for the paddle
    among the scene's cuboids is taken (a target inside a wall can only fail)."""
    near_clearance: tuple[float, float, float] = (0.07, 0.07, 0.01)
    """Room the paddle needs around its target, along each cuboid's axes, m: about its
    plate's half diagonal sideways, its thickness up and down."""

    def __post_init__(self) -> None:
        if not 0.0 < self.range_fraction <= 1.0:
            raise ValueError("range_fraction must be in (0, 1]")
        if self.rounds < 1 or self.ik_iterations < 1 or self.near_directions < 1:
            raise ValueError("rounds, ik_iterations and near_directions must be >= 1")


RETRACTED = np.array([0.0, -1.5, 0.0, -2.8, 0.0, 1.5, np.pi / 4])
"""Arm folded up and back over its base, clear of any table: the fallback start."""


def joint_bounds(fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """The central `fraction` of each joint range, (J,) each, rad."""
    centre = (fr3_limits.FR3.q_min + fr3_limits.FR3.q_max) / 2
    half = (fr3_limits.FR3.q_max - fr3_limits.FR3.q_min) / 2 * fraction
    return centre - half, centre + half


def random_configurations(rng: np.random.Generator, count: int, fraction: float) -> np.ndarray:
    """(count, J) uniform joint configurations within the central range."""
    low, high = joint_bounds(fraction)
    return rng.uniform(low, high, size=(count, len(low)))


def ik_seeds(rng: np.random.Generator, count: int, spread: float, fraction: float) -> np.ndarray:
    """(count, J) IK starting configurations: home plus N(0, spread) per joint, within the
    central `fraction` of each joint range."""
    low, high = joint_bounds(fraction)
    noise = rng.normal(0.0, spread, size=(count, len(low))) if spread > 0 else 0.0
    return np.clip(np.tile(fr3_limits.Q_HOME, (count, 1)) + noise, low, high)


def near_targets(
    rng: np.random.Generator,
    object_pos: np.ndarray,
    planar_radius: np.ndarray,
    cuboids: Cuboids,
    config: RobotInitConfig,
) -> np.ndarray:
    """(K, 3) points beside and a little above each object, m: of `near_directions` random
    directions, the first whose point leaves the paddle room among the cuboids (else the
    first: the collision check after the IK rejects it)."""
    count, tries = len(object_pos), config.near_directions
    angle = rng.uniform(0.0, 2.0 * np.pi, size=(count, tries))  # (K, T)
    distance = planar_radius[:, None] + rng.uniform(*config.near_gap, size=(count, tries))
    lift = rng.uniform(*config.near_lift, size=(count, tries))  # (K, T)
    offset = np.stack([np.cos(angle) * distance, np.sin(angle) * distance, lift], axis=2)
    candidates = object_pos[:, None, :] + offset  # (K, T, 3)
    blocked = inside_cuboids(candidates, cuboids, np.asarray(config.near_clearance))  # (K, T)
    first_clear = np.argmax(~blocked, axis=1)  # (K,), 0 when none is clear
    return candidates[np.arange(count), first_clear]


@dataclass(frozen=True)
class Cuboids:
    """The scene's cuboids of K environments (`scene.SceneBatch` fields)."""

    centre: np.ndarray  # (K, C, 3) m
    quat: np.ndarray  # (K, C, 4) wxyz
    half_extent: np.ndarray  # (K, C, 3) m
    active: np.ndarray  # (K, C) bool


def inside_cuboids(points: np.ndarray, cuboids: Cuboids, margin: np.ndarray) -> np.ndarray:
    """(K, T) whether each of T points (K, T, 3) lies within `margin` (3,) of an active
    cuboid of its environment, measured along the cuboid's own axes."""
    rotation = quaternion.to_matrix(cuboids.quat)  # (K, C, 3, 3)
    relative = points[:, :, None, :] - cuboids.centre[:, None, :, :]  # (K, T, C, 3)
    local = np.einsum("kcji,ktcj->ktci", rotation, relative)  # R^T (p - c), (K, T, C, 3)
    near = np.all(np.abs(local) <= cuboids.half_extent[:, None] + margin, axis=-1)  # (K, T, C)
    return np.any(near & cuboids.active[:, None, :], axis=-1)


class ArmKinematics:
    """The arm alone (its own model, a scratch MjData): kinematics and the paddle's Jacobian
    without the contacts and constraint solve a full forward pass of the world would run."""

    def __init__(self) -> None:
        self.model = fr3_model.load_mujoco()
        self.data = mujoco.MjData(self.model)
        self.site = self.model.site(fr3_model.EE_SITE).id
        self.qpos = fr3_model.robot_qpos_index(self.model)
        self.dof = fr3_model.robot_dof_index(self.model)
        self._jacp = np.zeros((3, self.model.nv))

    def paddle(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Paddle face position (3,) and its (3, J) translational Jacobian at `q` (J,)."""
        self.data.qpos[self.qpos] = q
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        mujoco.mj_jacSite(self.model, self.data, self._jacp, None, self.site)
        return self.data.site_xpos[self.site].copy(), self._jacp[:, self.dof]


def solve_ik(
    kinematics: ArmKinematics, q: np.ndarray, target: np.ndarray, config: RobotInitConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Damped least squares from `q` (K, J) towards paddle targets (K, 3).

    Returns:
        The configurations (K, J) and the remaining distance to each target (K,), m.
    """
    low, high = joint_bounds(config.range_fraction)
    q = q.copy()
    remaining = np.zeros(len(q))
    for k in range(len(q)):
        for _ in range(config.ik_iterations):
            position, jac = kinematics.paddle(q[k])
            error = target[k] - position  # (3,)
            remaining[k] = np.linalg.norm(error)
            if remaining[k] < config.ik_tolerance / 4:
                break
            gram = jac @ jac.T + config.ik_damping**2 * np.eye(3)
            q[k] = np.clip(q[k] + jac.T @ np.linalg.solve(gram, error), low, high)
        remaining[k] = np.linalg.norm(target[k] - kinematics.paddle(q[k])[0])
    return q, remaining


def arm_in_contact(physics: BatchPhysics, env_ids: np.ndarray) -> np.ndarray:
    """(K,) whether the arm of each environment touches anything (state already forwarded).

    A contact pushing on the arm shows as a constraint force on its joints; starts stay
    inside the joint ranges, so no joint-limit force can be mistaken for one.
    """
    force = physics.bind("qfrc_constraint")[np.ix_(env_ids, physics.world.robot_dof)]  # (K, J)
    return np.abs(force).max(axis=1) > 1e-6
