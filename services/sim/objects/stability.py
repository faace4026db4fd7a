"""Stable resting orientations, found by dropping the object on a plane in MuJoCo.

As in the paper (Object Placement, after CORN): drop the object from many random
orientations (with a little rolling friction, so rocking on faceted bottoms ends), keep the
drops that stopped turning, and group them by the object's down direction (a resting pose
is fixed up to yaw by which way is down). The centre of each frequent group is released
again without rolling friction; where it settles is the stored orientation, kept only if it
also comes back from small tilts at both ends of the object friction range, which rejects
knife-edge balances. Dropping, rather than a quasi-static analysis of the convex hull
(trimesh's `compute_stable_poses`), tests the poses against the collision geometry (the
convex parts, so a mug may rest on its handle), the contact model and the timestep the sim
uses. All drops run at once in one model: copies of the object that touch the plane only.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from hamnet.sim import quaternion
from hamnet.sim.objects.asset import StablePoses
from hamnet.sim.objects.config import StabilityConfig
from hamnet.sim.objects.mesh import Mesh
from hamnet.sim.objects.spec import DEFAULT_FRICTION, add_convex_body

DOWN = np.array([0.0, 0.0, -1.0])
DROP_MASS = 0.3
"""kg; the resting pose does not depend on it."""
GRID_SPACING = 1.0
"""m between drops; they cannot collide anyway, this only keeps the broad phase quiet."""


class UnstableObjectError(ValueError):
    """No orientation of the object came to a stable rest."""


def down_directions(quat: np.ndarray) -> np.ndarray:
    """(N, 3) world down (-z) expressed in the frames of objects at orientations (N, 4)."""
    return np.einsum("nij,i->nj", quaternion.to_matrix(quat), DOWN)  # R^T @ down


def tilt_quaternions(down: np.ndarray) -> np.ndarray:
    """(N, 4) smallest rotations taking object-frame unit directions `down` (N, 3) to -z."""
    axis = np.cross(down, DOWN)  # (N, 3)
    sin = np.linalg.norm(axis, axis=1)
    cos = down @ DOWN
    # Upside down (down = +z): any horizontal axis does; take x.
    axis = np.where(sin[:, None] > 1e-9, axis / np.maximum(sin, 1e-12)[:, None], [1.0, 0.0, 0.0])
    return quaternion.from_axis_angle(axis, np.arctan2(sin, cos))


def resting_geometry(points: np.ndarray, quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planar radius and resting height of a point set at each orientation.

    Args:
        points: (P, 3) object-frame points (surface and part vertices), m.
        quat: (K, 4) orientations, wxyz.
    Returns:
        (K,) largest horizontal distance from the centre, m; (K,) centre height above the
        lowest point, m.
    """
    world = np.einsum("kij,pj->kpi", quaternion.to_matrix(quat), points)  # (K, P, 3)
    return np.linalg.norm(world[..., :2], axis=-1).max(axis=1), -world[..., 2].min(axis=1)


def settle(
    parts: Sequence[Mesh],
    unit_inertia: np.ndarray,
    quat: np.ndarray,
    friction: np.ndarray,
    config: StabilityConfig,
    rolling_friction: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Release copies of the object just above a plane and let them come to rest.

    Args:
        parts: convex parts, object frame, m.
        unit_inertia: (3, 3) inertia per kg, m^2.
        quat: (N, 4) initial orientations, wxyz.
        friction: (N,) sliding friction of each copy's contacts.
        config: drop settings.
        rolling_friction: m; > 0 turns on MuJoCo's rolling friction (condim 6).
    Returns:
        (N, 3) each copy's down direction (object frame) averaged over the last
        `config.rest_window` seconds, which sits at the equilibrium of a slight rocking;
        (N,) whether it stayed within `config.rest_angle` meanwhile.
    """
    spec = mujoco.MjSpec()
    spec.option.timestep = config.timestep
    # Bitmasks: copies touch the plane (1 & 1) but never each other (2 & 1 = 0). MuJoCo
    # takes the larger friction of two geoms, so a frictionless plane leaves each copy's own.
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[0, 0, 1],
        contype=1,
        conaffinity=2,
        friction=[0.0, 0.0, 0.0],
        condim=6 if rolling_friction > 0 else 3,
    )
    points = np.concatenate([p.vertices for p in parts])  # (P, 3)
    _, heights = resting_geometry(points, quat)  # (N,)
    side = int(np.ceil(np.sqrt(len(quat))))
    for i, (q, h, mu) in enumerate(zip(quat, heights, friction)):
        pos = (GRID_SPACING * (i % side), GRID_SPACING * (i // side), h + config.drop_gap)
        add_convex_body(
            spec,
            f"drop{i}",
            parts,
            unit_inertia,
            DROP_MASS,
            mesh_prefix="object",
            friction=(mu, DEFAULT_FRICTION[1], rolling_friction),
            pos=pos,
            quat=q,
            contype=2,
            conaffinity=1,
        )
    model = spec.compile()
    data = mujoco.MjData(model)
    steps = int(round(config.settle_time / config.timestep))
    window = int(round(config.rest_window / config.timestep))
    drift = np.zeros(len(quat))  # (N,) largest move of the down direction in the window, rad
    mean_down = np.zeros((len(quat), 3))  # (N, 3)
    for step in range(steps):
        mujoco.mj_step(model, data)
        if step >= steps - window:
            down = down_directions(data.qpos.reshape(-1, 7)[:, 3:])  # (N, 3)
            if step == steps - window:
                start_down = down
            drift = np.maximum(drift, angle_between(down, start_down))
            mean_down += down
    return mean_down / np.linalg.norm(mean_down, axis=1, keepdims=True), drift < config.rest_angle


def cluster(down: np.ndarray, angle: float) -> list[np.ndarray]:
    """Group unit directions (N, 3): each joins the first group whose leader is within `angle`.

    Returns:
        Index arrays of the groups, in order of their leaders.
    """
    leaders: list[int] = []
    members: list[list[int]] = []
    for i, d in enumerate(down):
        for group, leader in enumerate(leaders):
            if d @ down[leader] > np.cos(angle):
                members[group].append(i)
                break
        else:
            leaders.append(i)
            members.append([i])
    return [np.array(m) for m in members]


def medoid(down: np.ndarray) -> np.ndarray:
    """The direction (3,) among (N, 3) closest on average to all the others."""
    return down[np.argmax((down @ down.T).sum(axis=1))]


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) angles between unit directions (N, 3) and (N, 3), rad."""
    return np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0))


def survives_tilt(
    parts: Sequence[Mesh],
    unit_inertia: np.ndarray,
    down: np.ndarray,
    config: StabilityConfig,
    rng: np.random.Generator,
    tilts: int = 4,
) -> np.ndarray:
    """Whether each resting direction (K, 3) returns after release tilted `config.check_tilt`.

    Each direction is released tilted about `tilts` evenly spread horizontal axes, at each
    of `config.check_frictions`, without rolling friction.
    Returns:
        (K,) bool.
    """
    heading = rng.uniform(0, 2 * np.pi) + np.arange(tilts) * 2 * np.pi / tilts  # (T,)
    axis = np.stack([np.cos(heading), np.sin(heading), np.zeros(tilts)], axis=1)  # (T, 3)
    tilt = quaternion.from_axis_angle(axis, np.full(tilts, config.check_tilt))  # (T, 4)
    frictions = np.asarray(config.check_frictions)  # (M,)
    k, t, m = len(down), tilts, len(frictions)
    start = quaternion.multiply(  # (K*T*M, 4), order (K, T, M)
        np.tile(np.repeat(tilt, m, axis=0), (k, 1)),
        np.repeat(tilt_quaternions(down), t * m, axis=0),
    )
    rest, _ = settle(parts, unit_inertia, start, np.tile(frictions, k * t), config)
    drift = angle_between(rest, np.repeat(down, t * m, axis=0))  # (K*T*M,)
    return (drift < config.stable_angle).reshape(k, t * m).all(axis=1)


def drop_candidates(
    parts: Sequence[Mesh],
    unit_inertia: np.ndarray,
    config: StabilityConfig,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Drop from random orientations and group the rests.

    Returns:
        (K, 3) down direction at the centre of each frequent group, most frequent first;
        (K,) share of the resting drops in it.
    """
    start = rng.normal(size=(config.drops, 4))  # (N, 4): uniform over rotations once normalised
    start /= np.linalg.norm(start, axis=1, keepdims=True)
    friction = np.full(config.drops, config.friction)  # (N,)
    down, still = settle(parts, unit_inertia, start, friction, config, config.rolling_friction)
    down = down[still]  # (S, 3)
    groups = cluster(down, config.cluster_angle)
    groups = sorted(
        (g for g in groups if len(g) >= config.min_probability * len(down)), key=len, reverse=True
    )
    groups = groups[: config.max_orientations]
    centres = np.array([medoid(down[g]) for g in groups]).reshape(-1, 3)  # (K, 3)
    return centres, np.array([len(g) / max(len(down), 1) for g in groups])


def merge(down: np.ndarray, probability: np.ndarray, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Fold directions (K, 3) within `angle` of a more probable one into it.

    Two groups of drops can settle to the same rest once released without rolling friction.
    Returns:
        The remaining directions and their summed probabilities, most probable first.
    """
    kept: list[int] = []
    total: list[float] = []
    for i in np.argsort(-probability, kind="stable"):
        for j, k in enumerate(kept):
            if down[i] @ down[k] > np.cos(angle):
                total[j] += probability[i]
                break
        else:
            kept.append(int(i))
            total.append(float(probability[i]))
    order = np.argsort(-np.array(total), kind="stable")
    return down[np.array(kept)[order]], np.array(total)[order]


def find_stable_poses(
    mesh: Mesh, parts: Sequence[Mesh], unit_inertia: np.ndarray, config: StabilityConfig
) -> StablePoses:
    """Stable resting orientations of an object, with planar radius and resting height.

    Drops (with rolling friction, to end rocking) give candidates; each is released again
    without rolling friction, whose rest is the stored orientation, and must survive the
    tilted releases of `survives_tilt`.

    Args:
        mesh: the surface, object frame (centre of mass at the origin), m.
        parts: the convex parts MuJoCo collides with.
        unit_inertia: (3, 3) inertia per kg, m^2.
        config: drop, grouping and check settings.
    Returns:
        Up to `config.max_orientations` poses, most probable first.
    Raises:
        UnstableObjectError: no drop came to rest, or no rest survived the checks.
    """
    rng = np.random.default_rng(config.seed)
    candidates, probability = drop_candidates(parts, unit_inertia, config, rng)
    friction = np.full(len(candidates), config.friction)  # (K,)
    rest, still = settle(parts, unit_inertia, tilt_quaternions(candidates), friction, config)
    keep = still & (angle_between(rest, candidates) < config.stable_angle)
    if keep.any():
        keep[keep] = survives_tilt(parts, unit_inertia, rest[keep], config, rng)
    if not keep.any():
        raise UnstableObjectError("no resting orientation survived the checks")
    down, probability = merge(rest[keep], probability[keep], config.cluster_angle)
    quat = tilt_quaternions(down)  # (K, 4)
    points = np.concatenate([mesh.vertices, *(p.vertices for p in parts)])  # (P, 3)
    radii, heights = resting_geometry(points, quat)
    return StablePoses(quat, probability, radii, heights)
