"""Where the arm starts an episode: "near" the object or "random" in the joint space.

The curriculum moves from near starts (the paddle within reach of the object, so contact is
found early) to random ones. Both are collision-free: a candidate whose arm touches the
scene or the object is rejected and drawn again, up to a bounded number of rounds, and the
retracted configuration (`RETRACTED`, then home) is the fallback of an environment that
never found one.

"near": damped-least-squares IK puts the paddle's contact face at a point beside the object
(a little above its centre, a random horizontal direction, `near_gap` metres beyond its
planar radius, further at each failed draw). The IK starts from a posture of a buffer drawn
once per process (`posture_buffer`, like the authors' precomputed IK solutions): one whose
paddle is near the target and whose arm, covered by spheres, clears the scene's cuboids and
the object (`near_seeds`). "random": uniform within the central part of each joint range.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.spatial import cKDTree

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
    """When no buffer posture near the target clears the scene, the IK starts from home
    plus N(0, this) per joint, rad: from home alone it finds the same arm posture again and
    again, and when that posture's elbow or wrist is in a wall or ceiling every draw fails."""
    rounds: int = 8
    """Draws per environment before falling back to the home configuration."""
    near_behind: float = math.pi
    """Half-width of the near starts' directions around the side of the object facing away
    from its goal, rad: at 0 the paddle starts straight behind the object for a push towards
    the goal; pi (the authors') allows every direction. The easy stage narrows it so that
    pushing, not walking around the object, is what a first policy has to learn."""
    near_directions: int = 8
    """Directions tried per near draw: the first whose target leaves room for the paddle
    among the scene's cuboids is taken (a target inside a wall can only fail)."""
    near_clearance: tuple[float, float, float] = (0.07, 0.07, 0.01)
    """Room the paddle needs around its target, along each cuboid's axes, m: about its
    plate's half diagonal sideways, its thickness up and down."""
    near_gap_growth: float = 0.04
    """Added to the gap at each further draw, m: under a tight ceiling often no posture fits
    beside the object (30-50% fallbacks there), so later draws move the target out, towards
    the case's open front."""
    near_gap_max: float = 0.2
    """Largest gap however many draws failed, m. The paper puts the end-effector within 0.1 m
    of the object (line 319); a 0.1 m cap leaves 5% of near starts retracted at the
    curriculum's first ceiling mix and 15% at its last (tight ceilings), 0.2 m leaves 1.6%
    and 4.2%, with 10-17% of near starts 0.15-0.2 m away (docs/sim.md)."""
    posture_count: int = 32768
    """Arm postures in the in-process buffer of IK seeds (`posture_buffer`), drawn uniformly
    within `range_fraction` of the joint ranges once per process."""
    posture_candidates: int = 32
    """Buffer postures whose paddle is nearest a near start's target; those whose arm clears
    the scene's cuboids and the object are the IK seeds (`near_seeds`)."""

    def __post_init__(self) -> None:
        if not 0.0 < self.range_fraction <= 1.0:
            raise ValueError("range_fraction must be in (0, 1]")
        if not 0.0 <= self.near_behind <= math.pi:
            raise ValueError(f"near_behind must be in [0, pi], got {self.near_behind}")
        if self.rounds < 1 or self.ik_iterations < 1 or self.near_directions < 1:
            raise ValueError("rounds, ik_iterations and near_directions must be >= 1")
        if not 1 <= self.posture_candidates <= self.posture_count:
            raise ValueError("posture_candidates must be in [1, posture_count]")


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
    draw: int = 0,
    goal_pos: np.ndarray | None = None,
) -> np.ndarray:
    """(K, 3) points beside and a little above each object, m: of `near_directions` random
    directions (within `near_behind` of the side away from `goal_pos` (K, 3) when it is
    narrower than pi), the first whose point leaves the paddle room among the cuboids (else
    the first: the collision check after the IK rejects it). Draw `draw` (0 first) widens
    the gap by `draw * near_gap_growth`."""
    count, tries = len(object_pos), config.near_directions
    if config.near_behind < np.pi and goal_pos is not None:
        away = object_pos[:, :2] - goal_pos[:, :2]  # (K, 2)
        behind = np.arctan2(away[:, 1], away[:, 0])  # (K,)
        angle = behind[:, None] + rng.uniform(
            -config.near_behind, config.near_behind, size=(count, tries)
        )
    else:
        angle = rng.uniform(0.0, 2.0 * np.pi, size=(count, tries))  # (K, T)
    gap = rng.uniform(*config.near_gap, size=(count, tries)) + draw * config.near_gap_growth
    gap = np.minimum(gap, config.near_gap_max)  # (K, T)
    distance = planar_radius[:, None] + gap  # (K, T)
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


@dataclass(frozen=True, eq=False)
class PostureBuffer:
    """N arm postures, where each puts the paddle, and spheres covering each arm: IK seeds
    that already bring the paddle near a target and whose arm can be checked against a
    scene before any IK or physics runs (the authors precompute IK solutions the same way,
    ham/src/ham/env/episode/robot_dof.py, `init_type: ik-presample`)."""

    q: np.ndarray
    """(N, J) joint positions, rad."""
    paddle: np.ndarray
    """(N, 3) paddle face centre (site `ee`), m."""
    sphere_centre: np.ndarray
    """(N, P, 3) float32 centres of P spheres covering the geoms of the arm's moving bodies,
    m (float32: the scene check streams (k, M, P, C) arrays, half the bytes)."""
    sphere_radius: np.ndarray
    """(P,) their radii, m."""
    on_paddle: np.ndarray
    """(P,) bool: the sphere covers the paddle, which is meant to be close to the object."""

    @functools.cached_property
    def paddle_tree(self) -> cKDTree:
        """k-d tree over `paddle`: nearest postures to a target in microseconds."""
        return cKDTree(self.paddle)


BOX_SPHERE_SPACING = 0.03
"""Grid spacing of the spheres covering a box geom (the paddle plate) over its two largest
axes, m: each sphere's radius is the half diagonal of its grid cell and the box's third
half size, 22 mm for the plate (15 spheres)."""


def _covering_spheres(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spheres covering every geom of the arm's moving bodies (never less than the geom, so
    a posture they call clear has no contact): along a capsule's or a cylinder's axis, at
    most a radius apart, each reaching the midpoints to its neighbours (up to 1.12 times the
    geom's radius); on a grid over a box's two largest axes (`BOX_SPHERE_SPACING`).

    Returns:
        geom ids (P,), centres in the geom frames (P, 3) m, radii (P,) m.
    """
    geoms, offsets, radii = [], [], []
    for geom in range(model.ngeom):
        if model.body_weldid[model.geom_bodyid[geom]] == 0:
            continue  # the base, welded to the world
        size = model.geom_size[geom]
        if model.geom_type[geom] == mujoco.mjtGeom.mjGEOM_BOX:
            axes = np.argsort(size)  # smallest first
            lines = [
                np.linspace(-size[a], size[a], int(np.ceil(2 * size[a] / BOX_SPHERE_SPACING)) + 1)
                for a in axes[1:]
            ]
            grid = np.stack(np.meshgrid(*lines, indexing="ij"), axis=-1).reshape(-1, 2)
            points = np.zeros((len(grid), 3))
            points[:, axes[1:]] = grid
            cell = [np.diff(line).max() / 2 for line in lines]
            radius = float(np.sqrt(size[axes[0]] ** 2 + cell[0] ** 2 + cell[1] ** 2))
        else:  # capsule or cylinder along z: radius size[0], half length size[1]
            z = np.linspace(-size[1], size[1], int(np.ceil(2 * size[1] / size[0])) + 1)
            points = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)
            step = z[1] - z[0] if len(z) > 1 else 0.0  # <= the geom's radius
            radius = float(np.hypot(size[0], step / 2))  # covers the slab up to the midpoints
        geoms += [geom] * len(points)
        offsets.append(points)
        radii += [radius] * len(points)
    return np.array(geoms), np.concatenate(offsets), np.array(radii)


@functools.cache
def posture_buffer(count: int, fraction: float, seed: int = 0) -> PostureBuffer:
    """`count` postures uniform within the central `fraction` of each joint range, computed
    once per process (about 0.2 s for 32768): a fixed table like the authors' precomputed
    file, independent of the sim's seed."""
    model = fr3_model.load_mujoco()
    data = mujoco.MjData(model)
    site = model.site(fr3_model.EE_SITE).id
    qpos = fr3_model.robot_qpos_index(model)
    geoms, offsets, radii = _covering_spheres(model)
    q = random_configurations(np.random.default_rng(seed), count, fraction)  # (N, J)
    paddle = np.zeros((count, 3))
    centres = np.zeros((count, len(geoms), 3))
    for n in range(count):
        data.qpos[qpos] = q[n]
        mujoco.mj_kinematics(model, data)
        paddle[n] = data.site_xpos[site]
        rotation = data.geom_xmat[geoms].reshape(-1, 3, 3)  # (P, 3, 3)
        centres[n] = data.geom_xpos[geoms] + np.einsum("pij,pj->pi", rotation, offsets)
    on_paddle = model.geom_bodyid[geoms] == model.body(fr3_model.PADDLE_BODY).id
    return PostureBuffer(q, paddle, centres.astype(np.float32), radii, on_paddle)


def near_seeds(
    rng: np.random.Generator,
    buffer: PostureBuffer,
    targets: np.ndarray,
    object_pos: np.ndarray,
    object_radius: np.ndarray,
    cuboids: Cuboids,
    candidates: int,
    nearest: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """IK seeds for near starts from the buffer: of the `candidates` postures whose paddle is
    nearest each target, one whose arm clears the scene's active cuboids and whose links
    (the paddle aside) clear the object: the nearest such in a first draw, a random one after.

    Args:
        targets: (K, 3) paddle targets, m; object_pos: (K, 3) m; object_radius: (K,) m.
    Returns:
        seeds (K, J) rad, and (K,) whether a clear posture was found (else the seed is the
        nearest posture, which the IK and the contact check may still accept).
    """
    _, index = buffer.paddle_tree.query(targets, k=candidates)  # (K, M), nearest first
    index = index.reshape(len(targets), candidates)
    clear = np.concatenate(
        [
            arm_clear(
                buffer, index[rows], object_pos[rows], object_radius[rows], _rows(cuboids, rows)
            )
            for rows in np.array_split(np.arange(len(targets)), max(1, len(targets) // 8))
        ]
    )  # (K, M), 8 environments at a time bound the (k, M, P, C, 3) arrays
    score = clear * (np.linspace(1.0, 0.5, candidates) if nearest else rng.random(clear.shape))
    pick = np.argmax(score, axis=1)  # (K,), the first posture when none is clear
    return buffer.q[index[np.arange(len(targets)), pick]], clear.any(axis=1)


def _rows(cuboids: Cuboids, rows: np.ndarray) -> Cuboids:
    return Cuboids(
        cuboids.centre[rows], cuboids.quat[rows], cuboids.half_extent[rows], cuboids.active[rows]
    )


def arm_clear(
    buffer: PostureBuffer,
    index: np.ndarray,
    object_pos: np.ndarray,
    object_radius: np.ndarray,
    cuboids: Cuboids,
) -> np.ndarray:
    """(k, M) whether postures `index` (k, M) keep every covering sphere out of the active
    cuboids, and the link spheres out of a sphere of `object_radius` (k,) at `object_pos`."""
    f32 = np.float32  # every (k, M, P, C) array in float32: half the bytes to stream
    centre = buffer.sphere_centre[index]  # (k, M, P, 3)
    rotation = quaternion.to_matrix(cuboids.quat).astype(f32)[:, None, None]  # (k,1,1,C,3,3)
    cuboid_centre = cuboids.centre.astype(f32)[:, None, None]  # (k, 1, 1, C, 3)
    half_extent = cuboids.half_extent.astype(f32)[:, None, None]  # (k, 1, 1, C, 3)
    relative = [
        centre[..., i, None] - cuboid_centre[..., i] for i in range(3)
    ]  # 3 x (k, M, P, C): per axis, smaller temporaries than one (k, M, P, C, 3) array
    squared = np.zeros_like(relative[0])
    for axis in range(3):  # (R^T (p - c))_axis, beyond the half extent
        local = sum(relative[i] * rotation[..., i, axis] for i in range(3))
        squared += np.maximum(np.abs(local) - half_extent[..., axis], 0.0) ** 2  # 0 inside
    radius = buffer.sphere_radius.astype(f32)
    hit = (squared < radius[:, None] ** 2) & cuboids.active[:, None, None, :]
    offset = centre - object_pos[:, None, None, :].astype(f32)  # (k, M, P, 3)
    touches = np.sqrt((offset**2).sum(axis=-1)) < object_radius[:, None, None] + radius
    return ~hit.any(axis=(2, 3)) & ~(touches & ~buffer.on_paddle).any(axis=2)


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
