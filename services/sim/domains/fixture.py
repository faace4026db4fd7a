"""Shared cuboid helpers of the benchmark domains: a fixture's per-episode shift and friction,
boxes by their corners, walls around a rectangle, the standing profile, and the assembly of a
domain's parts into the 16 slots of a `SceneBatch`.

A domain builder writes its fixture (cabinet, sink, ...) as a list of `Part`s in nominal world
coordinates; `Fixture` shifts them all by one per-episode offset. Part 0 is the support the
object stands on (its top is the batch's `table_top`, and the workspace bounds follow its
box, as for the procedural table in slot `TABLE`); the other parts fill slots 1, 2, ... in
order, and unused slots are parked inside part 0, beneath its top, as `scene.py` does.
Where objects may stand is a profile as in `scene_regions`: per axis up to 5 segments with
their lowest and highest elevation above the support's top, the surface being
max(profile_x, profile_y), so `regions` gives the 5 x 5 standing cells and `placement` the
footprint check. Shapes: B environments, N = 16 slots, R = 25 cells.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hamnet.sim import quaternion
from hamnet.sim.scene import ENV_CODE_COLUMNS, SceneBatch, checked_heights
from hamnet.sim.scene_config import FLOOR_Z, SceneConfig
from hamnet.sim.scene_regions import NUM_REGIONS, regions
from hamnet.task.cuboids import NUM_CUBOIDS, TABLE

JITTER_XY = 0.03
"""Half range of the uniform shift of a whole fixture along x and y per episode, m (our
choice: a real fixture stands a few centimetres elsewhere each time it is set up)."""
JITTER_Z = 0.02
"""Half range of the uniform shift of a whole fixture along z per episode, m (our choice)."""
SEGMENTS = 5
"""Segments per axis of a `SceneBatch` profile (plate, ramp, plate, ramp, plate there)."""

Length = float | np.ndarray
"""A coordinate: one float for every environment, or a (B,) array, m."""


class Part(NamedTuple):
    """One cuboid of a domain in the world frame, B environments."""

    centre: np.ndarray
    """(B, 3) m."""
    half_extent: np.ndarray
    """(B, 3) along the cuboid's own axes, m."""
    yaw: float = 0.0
    """Turn of the cuboid about the world z axis, rad."""


class Segments(NamedTuple):
    """The standing profile of one axis: n <= 5 segments between n + 1 nominal edges (m),
    each with its lowest and highest elevation above the support's top (m); a segment
    whose two differ (grill bars and the gaps between them) is no place to stand."""

    edges: Sequence[float]
    low: Sequence[Length]
    high: Sequence[Length] | None = None
    """None: every segment is a flat plate (high = low)."""


@dataclass(frozen=True)
class Fixture:
    """Where one domain's fixture stands in each environment and what its surfaces are."""

    offset: np.ndarray
    """(B, 3) shift of the whole fixture from its nominal place, m."""
    friction: np.ndarray
    """(B,) friction coefficient of its surfaces."""

    @classmethod
    def draw(cls, rng: np.random.Generator, num_envs: int, config: SceneConfig) -> Fixture:
        """A uniform shift within (JITTER_XY, JITTER_XY, JITTER_Z) and a friction from the
        procedural table's range (`SceneConfig.table_friction`, the paper's U(0.2, 0.6))."""
        half_range = np.array([JITTER_XY, JITTER_XY, JITTER_Z])
        offset = rng.uniform(-half_range, half_range, size=(num_envs, 3))  # (B, 3), m
        return cls(offset, rng.uniform(*config.table_friction, size=num_envs))

    @property
    def num_envs(self) -> int:
        """Number of environments B."""
        return len(self.friction)

    def point(self, x: Length, y: Length, z: Length) -> np.ndarray:
        """(B, 3) a nominal point moved with the fixture, m."""
        nominal = np.broadcast_arrays(x, y, z, np.zeros(self.num_envs))[:3]
        return np.stack(nominal, axis=-1) + self.offset

    def box(self, lo: Sequence[Length], hi: Sequence[Length]) -> Part:
        """The axis-aligned cuboid between nominal corners `lo` and `hi` (x, y, z), m."""
        low, high = self.point(*lo), self.point(*hi)
        return Part((low + high) / 2, (high - low) / 2)

    def yawed(self, centre: Sequence[Length], half_extent: Sequence[Length], yaw: float) -> Part:
        """A cuboid of `half_extent` (m) at nominal `centre` (m), turned by `yaw` about z."""
        half = np.stack(np.broadcast_arrays(*half_extent, np.zeros(self.num_envs))[:3], -1)
        return Part(self.point(*centre), half, yaw)

    def walls(
        self, x: Sequence[float], y: Sequence[float], z: Sequence[Length], thickness: float
    ) -> list[Part]:
        """Front (-x), back, right (-y) and left walls of `thickness` (m) just outside the
        rectangle `x` by `y` (m), from z[0] to z[1] (m); front and back cover the corners."""
        (x0, x1), (y0, y1), t = x, y, thickness
        return [
            self.box((x0 - t, y0 - t, z[0]), (x0, y1 + t, z[1])),
            self.box((x1, y0 - t, z[0]), (x1 + t, y1 + t, z[1])),
            self.box((x0, y0 - t, z[0]), (x1, y0, z[1])),
            self.box((x0, y1, z[0]), (x1, y1 + t, z[1])),
        ]

    def profile(self, x: Segments, y: Segments) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The standing profile: world edges (B, 2, 6) and lowest and highest elevations
        (B, 2, 5) above the support's top, m. Axes with fewer than 5 segments are padded
        with empty ones at their far end, which `regions` never calls flat."""
        edges, low, high = [], [], []
        for axis, segments in enumerate((x, y)):
            count = len(segments.low)
            if len(segments.edges) != count + 1 or not 1 <= count <= SEGMENTS:
                raise ValueError("an axis needs 1 to 5 segments and one edge more")
            pad = SEGMENTS - count
            nominal = np.asarray([*segments.edges, *[segments.edges[-1]] * pad])  # (6,)
            edges.append(nominal[None, :] + self.offset[:, axis, None])  # (B, 6)
            tops = segments.low if segments.high is None else segments.high
            for values, out in ((segments.low, low), (tops, high)):
                padded = [*values, *[values[-1]] * pad]
                out.append(np.stack(np.broadcast_arrays(*padded, np.zeros(self.num_envs))[:5], -1))
        return np.stack(edges, axis=1), np.stack(low, axis=1), np.stack(high, axis=1)


def prepare(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None
) -> tuple[np.ndarray, SceneConfig, Fixture]:
    """What every builder starts from: the checked heights (B,), m, the config (default
    `SceneConfig()`) and the fixture's draw."""
    config = config if config is not None else SceneConfig()
    object_height = checked_heights(object_height)  # (B,)
    return object_height, config, Fixture.draw(rng, len(object_height), config)


def cells(*pairs: tuple[int, int]) -> np.ndarray:
    """(R,) bool: the standing cells (x segment, y segment) named, as `regions` orders them."""
    mask = np.zeros((SEGMENTS, SEGMENTS), dtype=bool)
    for ix, iy in pairs:
        mask[ix, iy] = True
    return mask.reshape(NUM_REGIONS)


def either(first: np.ndarray, mask_a: np.ndarray, mask_b: np.ndarray) -> np.ndarray:
    """(B, R) `mask_a` (R,) where `first` (B,) holds, else `mask_b` (R,)."""
    return np.where(first[:, None], mask_a, mask_b)


def assemble(
    fixture: Fixture,
    parts: Sequence[Part],
    profile: tuple[np.ndarray, np.ndarray, np.ndarray],
    object_height: np.ndarray,
    config: SceneConfig,
    ceiling_z: np.ndarray | None = None,
    start_cells: np.ndarray | None = None,
    goal_cells: np.ndarray | None = None,
) -> SceneBatch:
    """The `SceneBatch` of one domain's fixture.

    Args:
        fixture: shift and friction per environment.
        parts: at most 16 cuboids; parts[0] is the support whose top is `table_top`.
        profile: world edges (B, 2, 6), low and high elevations (B, 2, 5) (`Fixture.profile`).
        object_height: (B,) height of the tallest resting pose of each object, m (checked).
        config: `hidden_half_extent` of parked slots and `table_origin` for the EnvCode.
        ceiling_z: (B,) world z of the lowest ceiling's underside above the standing cells,
            m; None: no ceiling.
        start_cells, goal_cells: (B, R) or (R,) bool, cells the start / goal may use;
            None: every flat one.
    Returns:
        The B scenes; `tight` is False (no procedural ceiling rule applies).
    """
    if not 1 <= len(parts) <= NUM_CUBOIDS:
        raise ValueError(f"a domain has 1 to {NUM_CUBOIDS} cuboids, got {len(parts)}")
    b = fixture.num_envs
    centre = np.zeros((b, NUM_CUBOIDS, 3))  # (B, N, 3), m
    half_extent = np.full((b, NUM_CUBOIDS, 3), config.hidden_half_extent)  # (B, N, 3), m
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (b, NUM_CUBOIDS, 1))  # (B, N, 4)
    active = np.zeros((b, NUM_CUBOIDS), dtype=bool)  # (B, N)
    for slot, part in enumerate(parts):
        centre[:, slot], half_extent[:, slot], active[:, slot] = part.centre, part.half_extent, True
        quat[:, slot] = quaternion.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.array(part.yaw))
    centre[:, len(parts) :] = centre[:, [TABLE]]  # parked inside the support, under its top
    table_top = centre[:, TABLE, 2] + half_extent[:, TABLE, 2]  # (B,), m
    ceiling_z = np.full(b, np.inf) if ceiling_z is None else np.asarray(ceiling_z, np.float64)
    edges, low, high = profile
    region_lo, region_hi, region_z, region_flat = regions(edges, low, high, table_top)
    every = np.ones((b, NUM_REGIONS), dtype=bool)
    return SceneBatch(
        centre=centre,
        quat=quat,
        half_extent=half_extent,
        active=active,
        friction=fixture.friction,
        env_code=_env_code(centre[:, TABLE], half_extent[:, TABLE], ceiling_z - table_top, config),
        object_height=object_height,
        table_top=table_top,
        tight=np.zeros(b, dtype=bool),
        ceiling_z=ceiling_z,
        profile_edges=edges,
        profile_low=low,
        profile_high=high,
        region_lo=region_lo,
        region_hi=region_hi,
        region_z=region_z,
        region_flat=region_flat,
        region_start=every if start_cells is None else every & start_cells,
        region_goal=every if goal_cells is None else every & goal_cells,
    )


def ceiling_clearance(nominal: float, object_height: np.ndarray, config: SceneConfig) -> np.ndarray:
    """(B,) clearance under a domain's ceiling, m: `nominal`, raised for a taller object to
    its height plus the tightest procedural gap (`SceneConfig.gap_height`), so every library
    object fits where the real fixture would hold it."""
    return np.maximum(nominal, np.asarray(object_height) + config.gap_height[0])


def _env_code(
    table_centre: np.ndarray, table_half: np.ndarray, clearance: np.ndarray, config: SceneConfig
) -> np.ndarray:
    """(B, 25) EnvCode of a domain: its support as the table (reaching the floor, so
    table_pos_z = 0 and table_dim_z = top - floor) and its ceiling's clearance; the
    procedural plate, ramp and wall columns are 0, having no counterpart in a fixture."""
    code = np.zeros((len(table_centre), len(ENV_CODE_COLUMNS)))  # (B, 25)
    column = {name: i for i, name in enumerate(ENV_CODE_COLUMNS)}
    top = table_centre[:, 2] + table_half[:, 2]  # (B,), m
    code[:, column["table_dim_x"]] = 2 * table_half[:, 0]
    code[:, column["table_dim_y"]] = 2 * table_half[:, 1]
    code[:, column["table_dim_z"]] = top - FLOOR_Z
    code[:, column["table_pos_x"]] = table_centre[:, 0] - config.table_origin[0]
    code[:, column["table_pos_y"]] = table_centre[:, 1] - config.table_origin[1]
    code[:, column["ceiling_height"]] = np.where(np.isfinite(clearance), clearance, 0.0)
    return code
