"""Ranges of the procedural cuboid scenes (paper, Table tab:env-param) and their geometry.

`SceneConfig` holds every distribution the scene sampler in `scene.py` draws from. Field
names follow the table (`table_dim_x` is `table_dim.x`); lengths are metres, angles radians.
The curriculum over ceiling types changes `p_tight` with `dataclasses.replace`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Range = tuple[float, float]
"""Closed interval (low, high) of a uniform distribution."""


def _check_range(name: str, value: Range, low: float = -math.inf) -> None:
    if len(value) != 2 or not low <= value[0] <= value[1]:
        raise ValueError(f"{name} must be (low, high) with {low} <= low <= high, got {value}")


@dataclass(frozen=True)
class SceneConfig:
    """Distributions of one procedural scene: table, interior plates, walls and ceiling."""

    table_dim_x: Range = (0.255, 0.51)
    """Table depth along x (away from the robot), m."""
    table_dim_y: Range = (0.325, 0.65)
    """Table width along y, m."""
    table_dim_z: Range = (0.2, 0.4)
    """Table thickness, m."""
    table_pos_x: Range = (0.0, 0.1)
    """Shift of the whole scene along x from `table_origin`, m."""
    table_pos_y: Range = (-0.15, 0.15)
    """Shift of the whole scene along y, m."""
    table_pos_z: Range = (0.1, 0.8)
    """Height of the table's bottom face above `table_origin`, m (shifts the whole scene)."""
    ramp_angle: Range = (0.0, math.radians(30.0))
    """Tilt of each interim plate from the vertical, rad: 0 is a step, larger is a gentler slope."""
    plate_height: Range = (0.0, 0.15)
    """Elevation of a top planar plate above the table top, m (bottom plates stay at 0)."""
    ceiling_height: Range = (0.3, 0.5)
    """Clearance of a nominal ceiling above the table top, before the platform rise, m."""
    gap_height: Range = (0.03, 0.05)
    """Clearance left above the object under a tight ceiling, m."""
    p_ceiling: float = 0.5
    """Probability that a scene has a ceiling (ceil_mask ~ B(p))."""
    p_wall: float = 0.5
    """Probability of each of the four walls (wall_mask ~ B(p)), before the ceiling's rules."""
    table_friction: Range = (0.2, 0.6)
    """Friction coefficient of every cuboid of the scene."""
    p_tight: float = 0.5
    """Probability of a tight ceiling rather than a nominal one; the curriculum raises it."""
    p_top_plate: float = 0.5
    """Probability that a planar plate is a top (elevated) plate rather than a bottom one."""
    plate_share_min: float = 0.1
    """Smallest share of an axis (after the ramps) that one planar plate takes."""
    table_origin: tuple[float, float, float] = (0.5, 0.0, -0.4)
    """World position of the table at table_pos = 0: centre in x, y; bottom face in z.

    The robot stands at the world origin looking along +x; -0.4 puts its base 0.4 m above
    the scene's floor, as in the authors' code."""
    embed_depth: float = 0.02
    """How far planar plates reach below the table top, so a low plate is never a sliver, m."""
    ramp_thickness: float = 0.02
    """Thickness of an interim plate (ramp), m."""
    wall_thickness: float = 0.02
    """Thickness of a wall, m; walls stand just outside the table's edges."""
    ceiling_thickness: float = 0.02
    """Thickness of the ceiling slab, m."""
    hidden_half_extent: float = 0.005
    """Half extent of an inactive cuboid, parked inside the table beneath its top, m."""

    def __post_init__(self) -> None:
        for name in ("table_dim_x", "table_dim_y", "table_dim_z", "ceiling_height"):
            _check_range(name, getattr(self, name), low=1e-3)
        for name in ("table_pos_x", "table_pos_y", "table_pos_z"):
            _check_range(name, getattr(self, name))
        for name in ("plate_height", "gap_height", "table_friction"):
            _check_range(name, getattr(self, name), low=0.0)
        _check_range("ramp_angle", self.ramp_angle, low=0.0)
        if self.ramp_angle[1] >= math.pi / 2:
            raise ValueError("ramp_angle must stay below 90 degrees (a horizontal ramp)")
        for name in ("p_ceiling", "p_wall", "p_tight", "p_top_plate"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be a probability, got {getattr(self, name)}")
        if not 0.0 <= self.plate_share_min < 1.0 / 3.0:
            raise ValueError("plate_share_min must be in [0, 1/3): three plates share an axis")
        for name in ("embed_depth", "ramp_thickness", "wall_thickness", "ceiling_thickness"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"{name} must be > 0")
        if not 0.0 < self.hidden_half_extent < self.table_dim_z[0] / 2:
            raise ValueError("hidden_half_extent must be > 0 and fit inside the thinnest table")
        if self.max_ramp_run * 2 >= min(self.table_dim_x[0], self.table_dim_y[0]):
            raise ValueError("two ramps at the steepest rise must leave room on the smallest table")

    @property
    def max_ramp_run(self) -> float:
        """Longest horizontal run of one ramp: the highest plate at the largest tilt, m."""
        return self.plate_height[1] * math.tan(self.ramp_angle[1])
