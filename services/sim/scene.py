"""Procedural cuboid scenes (paper, "Procedural domain and curriculum generation"), batched.

`sample_scenes` draws B scenes at once from a `numpy.random.Generator` and returns a
`SceneBatch`: 16 cuboid slots per environment (11 base, 5 case) as centre, orientation and
half-extent arrays with an active mask, the table friction, the 25-d scene parameter vector
(EnvCode) for the oracle ablation, and the flat regions objects may stand on. The slot count
never changes, so a MuJoCo model keeps 16 box geoms per environment and only moves and
resizes them; inactive slots are parked inside the table, beneath its top. The table and the
walls stand on the floor (`scene_config.FLOOR_Z`, where the robot's pedestal stands): the
table's box reaches from the floor to its top, so it never floats or sinks through it.

Frame: the robot stands at the world origin looking along +x; the table lies ahead of it.
Axis 0 is longitudinal (x, away from the robot), axis 1 lateral (y). Along each axis three
planar plates (top or bottom) and two interim plates (ramps) tile the table: a plate strip
spans the whole table across the other axis, so the surface elevation is
max(profile_x(x), profile_y(y)). Shapes: B environments, N = 16 cuboids, R = 25 regions.

This module owns the slot layout and assembles a batch: the parameters are drawn in
`scene_parameters`, the standing regions computed in `scene_regions`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hamnet.sim import quaternion
from hamnet.sim.scene_config import FLOOR_Z, SceneConfig
from hamnet.sim.scene_parameters import Case, Interior, sample_case, sample_interior
from hamnet.sim.scene_regions import profile, regions
from hamnet.task.cuboids import NUM_CUBOIDS, TABLE

PLATES = ((1, 2, 3), (6, 7, 8))
"""Planar plate slots per axis (x, y)."""
RAMPS = ((4, 5), (9, 10))
"""Interim plate slots per axis; ramp j joins planar plates j and j + 1."""
NUM_BASE = 11
"""Slots [0, 11) are the base (table and plates), [11, 16) the case (walls, ceiling)."""
FRONT_WALL, BACK_WALL, RIGHT_WALL, LEFT_WALL, CEILING = 11, 12, 13, 14, 15

ENV_CODE_COLUMNS = (
    "table_dim_x",
    "table_dim_y",
    "table_dim_z",
    "table_pos_x",
    "table_pos_y",
    "table_pos_z",
    "ramp_angle_x0",
    "ramp_angle_x1",
    "ramp_angle_y0",
    "ramp_angle_y1",
    "plate_height_x0",
    "plate_height_x1",
    "plate_height_x2",
    "plate_height_y0",
    "plate_height_y1",
    "plate_height_y2",
    "ramp_pos_x0",
    "ramp_pos_x1",
    "ramp_pos_y0",
    "ramp_pos_y1",
    "wall_height_front",
    "wall_height_back",
    "wall_height_right",
    "wall_height_left",
    "ceiling_height",
)
"""EnvCode columns. Metres and radians; ramp_pos is the centre of an interim plate along its
axis from the table centre; wall and ceiling heights are above the table top (the ceiling's
underside, platform rise included) and 0 when that cuboid is absent. table_dim_z and
table_pos_z are the sampled parameters whose sum sets the top (FLOOR_Z + pos + dim); the
table's box reaches from the floor to that top."""


@dataclass(frozen=True)
class SceneBatch:
    """B sampled scenes: cuboid slots, parameters and standing regions (world frame)."""

    centre: np.ndarray
    """(B, N, 3) cuboid centres, m."""
    quat: np.ndarray
    """(B, N, 4) cuboid orientations, unit quaternions wxyz."""
    half_extent: np.ndarray
    """(B, N, 3) cuboid half extents along their local axes, m."""
    active: np.ndarray
    """(B, N) bool: the cuboid is part of the scene; inactive ones are hidden in the table."""
    friction: np.ndarray
    """(B,) friction coefficient of the scene's surfaces."""
    env_code: np.ndarray
    """(B, 25) scene parameters, columns named by ENV_CODE_COLUMNS."""
    object_height: np.ndarray
    """(B,) object height the scene was built for (sets a tight ceiling), m."""
    table_top: np.ndarray
    """(B,) world z of the table top, m."""
    tight: np.ndarray
    """(B,) bool: the ceiling height (and wall height) follows the tight rule."""
    ceiling_z: np.ndarray
    """(B,) world z of the ceiling's underside, m; +inf without a ceiling."""
    profile_edges: np.ndarray
    """(B, 2, 6) world coordinate of the segment boundaries along x (row 0) and y (row 1)."""
    profile_low: np.ndarray
    """(B, 2, 5) lowest elevation of each segment above the table top, m."""
    profile_high: np.ndarray
    """(B, 2, 5) highest elevation of each segment above the table top, m."""
    region_lo: np.ndarray
    """(B, R, 2) xy corner of each region with the smallest coordinates, m."""
    region_hi: np.ndarray
    """(B, R, 2) xy corner of each region with the largest coordinates, m."""
    region_z: np.ndarray
    """(B, R) world z of a region's top face, m (meaningful where region_flat)."""
    region_flat: np.ndarray
    """(B, R) bool: the region is a horizontal face with some area, where objects may stand."""
    region_start: np.ndarray
    """(B, R) bool: the start may stand on the region (all True here; a benchmark domain
    keeps it apart from the goal, e.g. in a sink's basin while the goal is on its counter)."""
    region_goal: np.ndarray
    """(B, R) bool: the goal may stand on the region (all True here)."""

    @property
    def num_envs(self) -> int:
        """Number of environments B."""
        return len(self.friction)


def sample_scenes(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """Sample one scene per environment.

    Args:
        rng: source of randomness; the same generator state gives the same scenes.
        object_height: (B,) height of each environment's object, m; a tight ceiling leaves
            a gap of U(gap_height) above it.
        config: distributions; the default is the paper's Table tab:env-param.
    Returns:
        The B scenes.
    """
    config = config if config is not None else SceneConfig()
    object_height = checked_heights(object_height)  # (B,)
    num_envs = len(object_height)
    ranges = (config.table_dim_x, config.table_dim_y, config.table_dim_z)
    table_dim = rng.uniform(*np.transpose(ranges), size=(num_envs, 3))  # (B, 3), m
    ranges = (config.table_pos_x, config.table_pos_y, config.table_pos_z)
    table_pos = rng.uniform(*np.transpose(ranges), size=(num_envs, 3))  # (B, 3), m
    friction = rng.uniform(*config.table_friction, size=num_envs)  # (B,)
    interior = sample_interior(rng, table_dim[:, :2], config)
    case = sample_case(rng, object_height, interior.height.max(axis=(1, 2)), config)

    table_centre = np.asarray(config.table_origin) + table_pos[:, :2]  # (B, 2), m
    table_top = FLOOR_Z + table_pos[:, 2] + table_dim[:, 2]  # (B,), m
    centre, quat, half_extent, active = _cuboids(
        interior, case, table_centre, table_dim, table_top, config
    )
    profile_low, profile_high = profile(interior.height)
    profile_edges = interior.edges + table_centre[:, :, None]  # (B, 2, 6), m
    region_lo, region_hi, region_z, region_flat = regions(
        profile_edges, profile_low, profile_high, table_top
    )
    return SceneBatch(
        centre=centre,
        quat=quat,
        half_extent=half_extent,
        active=active,
        friction=friction,
        env_code=_env_code(table_dim, table_pos, interior, case),
        object_height=object_height,
        table_top=table_top,
        tight=case.tight,
        ceiling_z=np.where(case.ceiling, table_top + case.height, np.inf),
        profile_edges=profile_edges,
        profile_low=profile_low,
        profile_high=profile_high,
        region_lo=region_lo,
        region_hi=region_hi,
        region_z=region_z,
        region_flat=region_flat,
        region_start=np.ones_like(region_flat),
        region_goal=np.ones_like(region_flat),
    )


def checked_heights(object_height: np.ndarray) -> np.ndarray:
    """`object_height` as a (B,) float64 array, m.

    Raises:
        ValueError: it is not a (B,) array of positive heights.
    """
    object_height = np.asarray(object_height, dtype=np.float64)
    if object_height.ndim != 1 or not np.all(object_height > 0):
        raise ValueError("object_height must be a (B,) array of positive heights")
    return object_height


def _cuboids(
    interior: Interior,
    case: Case,
    table_centre: np.ndarray,
    table_dim: np.ndarray,
    table_top: np.ndarray,
    config: SceneConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """All 16 slots: centre (B, N, 3), quat (B, N, 4), half extent (B, N, 3), active (B, N).

    Inactive slots are parked inside the table, beneath its top: the slot stays, so the
    simulator only moves and resizes its boxes.
    """
    num_envs = len(table_top)
    centre = np.zeros((num_envs, NUM_CUBOIDS, 3))  # (B, N, 3)
    half_extent = np.zeros((num_envs, NUM_CUBOIDS, 3))  # (B, N, 3)
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (num_envs, NUM_CUBOIDS, 1))  # (B, N, 4)
    active = np.zeros((num_envs, NUM_CUBOIDS), dtype=bool)  # (B, N)
    # The table's box reaches the floor: table_dim_z only sets, with table_pos_z, its top.
    centre[:, TABLE] = np.column_stack([table_centre, (table_top + FLOOR_Z) / 2])
    half_extent[:, TABLE] = np.column_stack([table_dim[:, :2] / 2, (table_top - FLOOR_Z) / 2])
    active[:, TABLE] = True
    boxes = (centre, quat, half_extent, active)
    _place_interior(boxes, interior, table_centre, table_dim, table_top, config)
    _place_case(boxes, case, table_centre, table_dim, table_top, config)
    hidden = ~active
    centre[hidden] = np.broadcast_to(centre[:, [TABLE]], centre.shape)[hidden]
    half_extent[hidden] = config.hidden_half_extent
    quat[hidden] = [1.0, 0.0, 0.0, 0.0]
    return centre, quat, half_extent, active


def _place_interior(
    boxes: tuple[np.ndarray, ...],
    interior: Interior,
    table_centre: np.ndarray,
    table_dim: np.ndarray,
    table_top: np.ndarray,
    config: SceneConfig,
) -> None:
    """Write the planar and interim plate slots of `boxes` (centre, quat, half, active)."""
    centre, quat, half_extent, active = boxes
    for axis in (0, 1):
        other = 1 - axis
        edges = interior.edges[:, axis]  # (B, 6)
        for i, slot in enumerate(PLATES[axis]):
            height = interior.height[:, axis, i]  # (B,)
            # A solid block from below the table top up to the plate's top face.
            start, end = edges[:, 2 * i], edges[:, 2 * i + 1]  # (B,) plate segment
            centre[:, slot, axis] = table_centre[:, axis] + (start + end) / 2
            centre[:, slot, other] = table_centre[:, other]
            centre[:, slot, 2] = table_top + (height - config.embed_depth) / 2
            half_extent[:, slot, axis] = (end - start) / 2
            half_extent[:, slot, other] = table_dim[:, other] / 2
            half_extent[:, slot, 2] = (height + config.embed_depth) / 2
            active[:, slot] = height > 0
        for j, slot in enumerate(RAMPS[axis]):
            low, high = edges[:, 2 * j + 1], edges[:, 2 * j + 2]  # (B,) ramp segment
            z0, z1 = interior.height[:, axis, j], interior.height[:, axis, j + 1]
            run, rise = high - low, z1 - z0
            length = np.hypot(run, rise)  # (B,) along the slope, m
            is_ramp = rise != 0
            # Unit slope direction (u_s, u_z) and the top face's normal (-u_z, u_s).
            u_s = np.where(is_ramp, run / np.where(is_ramp, length, 1.0), 1.0)
            u_z = np.where(is_ramp, rise / np.where(is_ramp, length, 1.0), 0.0)
            # The top face joins the two plates' edges; the slab lies beneath it.
            half_t = config.ramp_thickness / 2
            centre[:, slot, axis] = table_centre[:, axis] + (low + high) / 2 + u_z * half_t
            centre[:, slot, other] = table_centre[:, other]
            centre[:, slot, 2] = table_top + (z0 + z1) / 2 - u_s * half_t
            half_extent[:, slot, axis] = length / 2
            half_extent[:, slot, other] = table_dim[:, other] / 2
            half_extent[:, slot, 2] = half_t
            # Rotating about z x e_axis by atan2(-u_z, u_s) turns e_axis onto the slope.
            hinge = np.cross([0.0, 0.0, 1.0], np.eye(3)[axis])
            quat[:, slot] = quaternion.from_axis_angle(hinge, np.arctan2(-u_z, u_s))
            active[:, slot] = is_ramp


def _place_case(
    boxes: tuple[np.ndarray, ...],
    case: Case,
    table_centre: np.ndarray,
    table_dim: np.ndarray,
    table_top: np.ndarray,
    config: SceneConfig,
) -> None:
    """Write the wall and ceiling slots: walls stand just outside the table's edges, from
    the floor to their height; the ceiling covers the table and the walls."""
    centre, _, half_extent, active = boxes
    thickness = config.wall_thickness
    bottom, top = FLOOR_Z, table_top + case.wall_height  # (B,), m
    for k, slot in enumerate((FRONT_WALL, BACK_WALL, RIGHT_WALL, LEFT_WALL)):
        axis, side = divmod(k, 2)  # front/back face x, right/left face y
        sign = 2 * side - 1  # -1 for front and right
        other = 1 - axis
        centre[:, slot, axis] = table_centre[:, axis] + sign * (table_dim[:, axis] + thickness) / 2
        centre[:, slot, other] = table_centre[:, other]
        centre[:, slot, 2] = (bottom + top) / 2
        half_extent[:, slot, axis] = thickness / 2
        # Front and back walls also cover the corners.
        half_extent[:, slot, other] = table_dim[:, other] / 2 + (thickness if axis == 0 else 0.0)
        half_extent[:, slot, 2] = (top - bottom) / 2
        active[:, slot] = case.wall[:, k]
    centre[:, CEILING, :2] = table_centre
    centre[:, CEILING, 2] = table_top + case.height + config.ceiling_thickness / 2
    half_extent[:, CEILING, :2] = table_dim[:, :2] / 2 + thickness
    half_extent[:, CEILING, 2] = config.ceiling_thickness / 2
    active[:, CEILING] = case.ceiling


def _env_code(
    table_dim: np.ndarray, table_pos: np.ndarray, interior: Interior, case: Case
) -> np.ndarray:
    """The (B, 25) EnvCode in the order of ENV_CODE_COLUMNS."""
    num_envs = len(table_dim)
    edges = interior.edges
    ramp_pos = (edges[..., [1, 3]] + edges[..., [2, 4]]) / 2  # (B, 2, 2), m
    return np.concatenate(
        [
            table_dim,  # 3
            table_pos,  # 3
            interior.angle.reshape(num_envs, 4),  # 4
            interior.height.reshape(num_envs, 6),  # 6
            ramp_pos.reshape(num_envs, 4),  # 4
            case.wall * case.wall_height[:, None],  # 4
            (case.ceiling * case.height)[:, None],  # 1
        ],
        axis=-1,
    )
