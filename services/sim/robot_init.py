"""Where the arm starts an episode: "near" the object or "random" in the joint space.

The curriculum moves from near starts (the paddle within reach of the object, so contact is
found early) to random ones. Both are collision-free: a candidate whose arm touches the
scene or the object is rejected and drawn again, up to a bounded number of rounds, and the
home configuration is the fallback of an environment that never found one.

"near": damped-least-squares IK, batched over environments, puts the paddle's contact face
at a point beside the object (at its height, a random horizontal direction, `near_gap`
metres beyond its planar radius). "random": uniform within the central part of each joint
range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hamnet.sim import robot
from hamnet.sim.physics import BatchPhysics


@dataclass(frozen=True)
class RobotInitConfig:
    """How initial arm configurations are drawn."""

    range_fraction: float = 0.9
    """Random starts and IK stay within this central fraction of each joint range."""
    near_gap: tuple[float, float] = (0.02, 0.08)
    """Distance from the object's planar radius to the paddle's face for near starts, m."""
    ik_iterations: int = 40
    """Damped-least-squares iterations per near start."""
    ik_damping: float = 0.05
    """Damping of the least squares, m."""
    ik_tolerance: float = 0.03
    """A near start must bring the paddle within this distance of its target, m."""
    rounds: int = 4
    """Draws per environment before falling back to the home configuration."""

    def __post_init__(self) -> None:
        if not 0.0 < self.range_fraction <= 1.0:
            raise ValueError("range_fraction must be in (0, 1]")
        if self.rounds < 1 or self.ik_iterations < 1:
            raise ValueError("rounds and ik_iterations must be >= 1")


def joint_bounds(fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """The central `fraction` of each joint range, (J,) each, rad."""
    centre = (robot.FR3.q_min + robot.FR3.q_max) / 2
    half = (robot.FR3.q_max - robot.FR3.q_min) / 2 * fraction
    return centre - half, centre + half


def random_configurations(rng: np.random.Generator, count: int, fraction: float) -> np.ndarray:
    """(count, J) uniform joint configurations within the central range."""
    low, high = joint_bounds(fraction)
    return rng.uniform(low, high, size=(count, len(low)))


def near_targets(
    rng: np.random.Generator, object_pos: np.ndarray, planar_radius: np.ndarray, gap: tuple[float, float]
) -> np.ndarray:
    """(K, 3) points beside each object: at its centre height, a random direction, m."""
    angle = rng.uniform(0.0, 2.0 * np.pi, size=len(object_pos))  # (K,)
    distance = planar_radius + rng.uniform(*gap, size=len(object_pos))  # (K,)
    offset = np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=1) * distance[:, None]
    return object_pos + offset


def solve_ik(
    physics: BatchPhysics, env_ids: np.ndarray, q: np.ndarray, target: np.ndarray, config: RobotInitConfig
) -> np.ndarray:
    """Move the paddle of `env_ids` towards `target` (K, 3) from `q` (K, J); returns (K, J).

    Writes the arm's qpos of those environments (the caller resets them afterwards).
    """
    world = physics.world
    low, high = joint_bounds(config.range_fraction)
    body = world.model.site_bodyid[world.ee_site]
    site_pos = physics.bind("site_xpos")
    for _ in range(config.ik_iterations):
        physics.qpos[np.ix_(env_ids, world.robot_qpos)] = q
        physics.batch.forward(env_ids)
        error = target - site_pos[env_ids, world.ee_site]  # (K, 3)
        jacp, _ = physics.batch.jac(body, site_pos[env_ids, world.ee_site], env_ids)
        jac = jacp[:, :, world.robot_dof]  # (K, 3, J)
        gram = jac @ jac.transpose(0, 2, 1) + config.ik_damping**2 * np.eye(3)  # (K, 3, 3)
        step = jac.transpose(0, 2, 1) @ np.linalg.solve(gram, error[:, :, None])  # (K, J, 1)
        q = np.clip(q + step[:, :, 0], low, high)
    physics.qpos[np.ix_(env_ids, world.robot_qpos)] = q
    physics.batch.forward(env_ids)
    return q


def arm_in_contact(physics: BatchPhysics, env_ids: np.ndarray) -> np.ndarray:
    """(K,) whether the arm of each environment touches anything (state already forwarded)."""
    robot_bodies = physics.world.robot_bodies
    touching = np.zeros(len(env_ids), dtype=bool)
    for k, env in enumerate(env_ids):
        data = physics.batch.get_data(int(env))
        bodies = physics.world.model.geom_bodyid[[data.contact.geom1, data.contact.geom2]]  # (2, C)
        touching[k] = bool(np.isin(bodies, robot_bodies).any())
    return touching


def paddle_distance(physics: BatchPhysics, env_ids: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(K,) distance from the paddle's face to `target` (K, 3) in the current state, m."""
    site_pos = physics.bind("site_xpos")[env_ids, physics.world.ee_site]  # (K, 3)
    return np.linalg.norm(site_pos - target, axis=1)
