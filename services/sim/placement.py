"""Goal and start poses of the object on a scene's flat faces (paper, appendix "Object
Placement"), by vectorized rejection sampling.

Consumes a `SceneBatch` and, per environment, the object's K precomputed stable orientations
with their planar radius, resting height and top height; produces a `Placement`: goal and
start positions and wxyz quaternions and a validity mask. Each environment draws a fixed
number of candidates at once and keeps the first that passes, so there is no loop that
could run forever: an environment with no passing candidate is reported invalid (resample
its scene). The goal is drawn first, biased toward elevated plates; the start then prefers
faces lower than the goal and keeps its distance from the goal in position or orientation
(the authors' rule, so in-place reorientations occur), so an episode never starts in
success. Goal and start draw only from the regions the scene's `region_goal` and
`region_start` allow (every region in a procedural scene). Shapes: B environments, K stable orientations,
T tries, R regions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hamnet.sim import quaternion
from hamnet.sim.scene import SceneBatch


@dataclass(frozen=True)
class PlacementConfig:
    """How goal and start poses are drawn."""

    min_position_separation: float = 0.05
    """A start this far from the goal's position or farther is accepted, m: the success
    radius (the authors accept a pair when pos_err > goal_radius or orn_err > goal_angle,
    ham/src/ham/env/episode/goal_obj_pose.py:164-167, with goal_radius 0.05,
    rss_train.yaml:122, scaled by sample_thresh 1.0, rss_train.yaml:132-134)."""
    min_orientation_separation: float = 0.1
    """... or this far from its orientation, rad: the success angle (rss_train.yaml:123)."""
    max_position_separation: float = math.inf
    """A start farther than this from the goal's position is refused, m: caps the push
    distance of an easy training stage (inf: no cap, as the paper and the authors)."""
    require_both_separations: bool = False
    """True: the start must differ in position and in orientation (no in-place
    reorientation or pure translation: stricter than the authors)."""
    elevated_goal_bias: float = 10.0
    """Weight, relative to 1, of faces above the table top when drawing the goal, and of faces
    lower than the goal when drawing the start; 1 draws both by area alone."""
    max_tries: int = 64
    """Candidates drawn per environment for the goal, and again for the start."""
    max_scene_draws: int = 100
    """Scenes drawn for an environment whose placement keeps failing, before giving up with
    an error; a large object often fits nowhere on a small table (up to 80% of scenes at a
    0.1 m bounding radius)."""
    random_yaw: bool = True
    """Turn each stable orientation by a uniform yaw about the world z axis."""
    start_keeps_goal_orientation: bool = False
    """The start takes the goal's stable pose and yaw, so reaching the goal is a pure
    translation (an easy training stage); False: drawn independently, as the paper."""

    def __post_init__(self) -> None:
        if self.min_position_separation < 0 or self.min_orientation_separation < 0:
            raise ValueError("separations must be >= 0")
        if self.max_position_separation <= self.min_position_separation:
            raise ValueError("max_position_separation must exceed min_position_separation")
        if self.elevated_goal_bias <= 0:
            raise ValueError("elevated_goal_bias must be > 0 (1 means no bias)")
        if self.max_tries < 1 or self.max_scene_draws < 1:
            raise ValueError("max_tries and max_scene_draws must be >= 1")


@dataclass(frozen=True)
class Placement:
    """Goal and start poses of the object in each environment (world frame)."""

    goal_pos: np.ndarray
    """(B, 3) object position at the goal, m."""
    goal_quat: np.ndarray
    """(B, 4) object orientation at the goal, wxyz."""
    goal_pose: np.ndarray
    """(B,) index of the goal's stable orientation among the K."""
    start_pos: np.ndarray
    """(B, 3) object position at the start, m."""
    start_quat: np.ndarray
    """(B, 4) object orientation at the start, wxyz."""
    start_pose: np.ndarray
    """(B,) index of the start's stable orientation among the K."""
    valid: np.ndarray
    """(B,) bool: both poses passed every check; other rows hold unchecked candidates."""


class _Candidates(NamedTuple):
    pos: np.ndarray  # (B, T, 3) m
    quat: np.ndarray  # (B, T, 4) wxyz
    pose: np.ndarray  # (B, T) stable orientation index
    surface_z: np.ndarray  # (B, T) world z of the face the object rests on, m
    valid: np.ndarray  # (B, T) bool


def sample_placements(
    rng: np.random.Generator,
    scene: SceneBatch,
    stable_quat: np.ndarray,
    planar_radius: np.ndarray,
    rest_height: np.ndarray,
    top_height: np.ndarray,
    config: PlacementConfig | None = None,
    pose_weight: np.ndarray | None = None,
) -> Placement:
    """Draw a goal and a start pose per environment.

    Args:
        rng: source of randomness; the same generator state gives the same placements.
        scene: the B scenes.
        stable_quat: (B, K, 4) stable orientations, wxyz.
        planar_radius: (B, K) largest horizontal distance from the object's origin to its
            surface in each orientation, m: the margin kept from walls and plate edges.
        rest_height: (B, K) height of the object's origin above the face it rests on, m.
        pose_weight: (B, K) how often each orientation is drawn (e.g. how often it occurs
            when the object is dropped; 0 for padding), None for uniform.
        top_height: (B, K) height of the object's top above that face, m (ceiling check).
        config: sampling options.
    Returns:
        The placements; rows with `valid` False found no acceptable pose.
    """
    config = config if config is not None else PlacementConfig()
    num_envs, num_poses = planar_radius.shape
    if stable_quat.shape != (num_envs, num_poses, 4) or num_envs != scene.num_envs:
        raise ValueError("stable_quat must be (B, K, 4) and B must match the scene")
    if rest_height.shape != planar_radius.shape or top_height.shape != planar_radius.shape:
        raise ValueError("planar_radius, rest_height and top_height must all be (B, K)")
    if not (np.all(planar_radius > 0) and np.all(rest_height >= 0)):
        raise ValueError("planar_radius must be > 0 and rest_height >= 0")
    if pose_weight is None:
        pose_weight = np.ones_like(planar_radius)
    if pose_weight.shape != planar_radius.shape or not np.all(pose_weight.sum(axis=1) > 0):
        raise ValueError("pose_weight must be (B, K) with a positive sum per row")
    objects = (stable_quat, planar_radius, rest_height, top_height, pose_weight)
    area = np.prod(scene.region_hi - scene.region_lo, axis=-1) * scene.region_flat  # (B, R)
    bias = config.elevated_goal_bias
    elevated = scene.region_z > scene.table_top[:, None]  # (B, R)
    goal_weight = area * np.where(elevated, bias, 1.0) * scene.region_goal  # (B, R)
    goal = _pick(_candidates(rng, scene, goal_weight, objects, config))

    lower = scene.region_z < goal.surface_z[:, None]  # (B, R)
    orientation = (goal.pose, goal.quat) if config.start_keeps_goal_orientation else None
    start_weight = area * np.where(lower, bias, 1.0) * scene.region_start  # (B, R)
    start = _candidates(rng, scene, start_weight, objects, config, orientation)
    distance = np.linalg.norm(start.pos - goal.pos[:, None], axis=-1)  # (B, T), m
    angle = quaternion.angle_between(start.quat, goal.quat[:, None])  # (B, T), rad
    far = distance >= config.min_position_separation  # (B, T)
    turned = angle >= config.min_orientation_separation  # (B, T)
    separated = (far & turned) if config.require_both_separations else (far | turned)
    separated &= distance <= config.max_position_separation
    start = _pick(start._replace(valid=start.valid & separated))
    return Placement(
        goal_pos=goal.pos,
        goal_quat=goal.quat,
        goal_pose=goal.pose,
        start_pos=start.pos,
        start_quat=start.quat,
        start_pose=start.pose,
        valid=goal.valid & start.valid,
    )


def _categorical(rng: np.random.Generator, weight: np.ndarray, count: int) -> np.ndarray:
    """(B, count) indices drawn per row with probabilities proportional to `weight` (B, N)."""
    cdf = np.cumsum(weight, axis=-1)  # (B, N)
    draw = rng.random((weight.shape[0], count)) * cdf[:, -1:]  # (B, count)
    return np.minimum((cdf[:, None, :] <= draw[..., None]).sum(axis=-1), weight.shape[1] - 1)


def _candidates(
    rng: np.random.Generator,
    scene: SceneBatch,
    weight: np.ndarray,
    objects: tuple[np.ndarray, ...],
    config: PlacementConfig,
    orientation: tuple[np.ndarray, np.ndarray] | None = None,
) -> _Candidates:
    """T poses per environment: a stable orientation, a region drawn by `weight` (B, R), a
    uniform point in it and a yaw; valid where the footprint is flat and under the ceiling.
    `orientation`, a stable pose index (B,) and quaternion (B, 4), fixes every candidate's
    orientation instead."""
    stable_quat, planar_radius, rest_height, top_height, pose_weight = objects
    shape = (planar_radius.shape[0], config.max_tries)
    if orientation is None:
        pose = _categorical(rng, pose_weight, shape[1])  # (B, T)
    else:
        pose = np.repeat(orientation[0][:, None], shape[1], axis=1)  # (B, T)
    region = _categorical(rng, weight, shape[1])  # (B, T)
    lo = np.take_along_axis(scene.region_lo, region[..., None], axis=1)  # (B, T, 2)
    hi = np.take_along_axis(scene.region_hi, region[..., None], axis=1)  # (B, T, 2)
    xy = lo + rng.random((*shape, 2)) * (hi - lo)  # (B, T, 2), m
    yaw = rng.uniform(-np.pi, np.pi, size=shape) if config.random_yaw else np.zeros(shape)

    radius = np.take_along_axis(planar_radius, pose, axis=1)  # (B, T), m
    flat, elevation = _flat_footprint(scene, xy, radius)
    surface_z = scene.table_top[:, None] + elevation  # (B, T), m
    top_z = surface_z + np.take_along_axis(top_height, pose, axis=1)  # (B, T), m
    valid = (weight.sum(axis=-1, keepdims=True) > 0) & flat & (top_z <= scene.ceiling_z[:, None])
    z = surface_z + np.take_along_axis(rest_height, pose, axis=1)  # (B, T), m
    stable = np.take_along_axis(stable_quat, pose[..., None], axis=1)  # (B, T, 4)
    turn = quaternion.from_axis_angle(np.array([0.0, 0.0, 1.0]), yaw)  # (B, T, 4)
    quat = quaternion.multiply(turn, stable)
    if orientation is not None:
        quat = np.repeat(orientation[1][:, None], shape[1], axis=1)  # (B, T, 4)
    return _Candidates(
        pos=np.concatenate([xy, z[..., None]], axis=-1),
        quat=quat,
        pose=pose,
        surface_z=surface_z,
        valid=valid,
    )


def _flat_footprint(
    scene: SceneBatch, xy: np.ndarray, radius: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Whether the square of half side `radius` (B, T) around `xy` (B, T, 2) lies on the
    table at one elevation, and the highest elevation under it (B, T), m.

    The surface is max(profile_x, profile_y), so over the square it ranges from
    max(low_x, low_y) to max(high_x, high_y), each taken over the segments the square
    overlaps along that axis; equal ends mean no edge, step or slope under the object.
    The square holds the object's bounding circle, so the check errs on the safe side.
    """
    inside = np.ones(radius.shape, dtype=bool)
    low, high = [], []
    for axis in (0, 1):
        edges = scene.profile_edges[:, axis, None, :]  # (B, 1, 6)
        start = xy[..., axis] - radius  # (B, T)
        end = xy[..., axis] + radius
        inside &= (start >= edges[..., 0]) & (end <= edges[..., -1])
        overlap = (edges[..., :-1] < end[..., None]) & (edges[..., 1:] > start[..., None])
        high.append(np.where(overlap, scene.profile_high[:, axis, None], -np.inf).max(-1))
        low.append(np.where(overlap, scene.profile_low[:, axis, None], np.inf).min(-1))
    top = np.maximum(*high)  # (B, T)
    return inside & (top == np.maximum(*low)), top


def _pick(candidates: _Candidates) -> _Candidates:
    """The first valid candidate of each environment (the first one where none is)."""
    first = np.argmax(candidates.valid, axis=1)  # (B,)
    rows = np.arange(len(first))
    return _Candidates(*(field[rows, first] for field in candidates))
