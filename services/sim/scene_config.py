"""Ranges of the procedural cuboid scenes (paper, Table tab:env-param) and their geometry.

`SceneConfig` holds every distribution the scene sampler (`scene.py`, `scene_parameters.py`)
draws from. Field names follow the table (`table_dim_x` is `table_dim.x`); lengths are
metres, angles radians. Where the paper's table is ambiguous or differs, the defaults are
the authors' training configuration (ham/src/ham/data/cfg/rss_train.yaml and the scene code
it selects; file and line in each field's docstring); `SCENE_PRESETS["paper"]` keeps the
paper's text. The curriculum over ceiling types changes `p_tight` with `dataclasses.replace`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Range = tuple[float, float]
"""Closed interval (low, high) of a uniform distribution."""

FLOOR_Z = -0.4
"""World z of the floor that the table and the robot's pedestal stand on, m. The robot's base
is the world origin, 0.4 m above the floor as in the authors' code
(ham/src/ham/env/episode/robot_pos.py:49, `base_height: table`), whose table bottom sits on
the floor at table_pos.z = 0 (ham/src/ham/env/episode/table_pos.py:37-39)."""


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
    table_pos_z: Range = (0.0, 0.6)
    """Rise of the table top, m: the top is at FLOOR_Z + table_pos_z + table_dim_z, so
    -0.2 to +0.6 m from the robot's base (authors: min/max_table_height_offset,
    tabletop_with_object_scene_v3.py:146-147 and 331-332, use_table_height_dr
    rss_train.yaml:73; the paper's table says U(0.1, 0.8)). Their slab then floats above
    the floor; ours reaches down to it (`scene.py`), so no camera sees a floating table."""
    ramp_angle: Range = (0.0, math.radians(30.0))
    """Tilt of each interim plate from the vertical, rad: 0 is a step, larger is a gentler slope."""
    plate_height: Range = (0.05, 0.15)
    """Elevation of a top planar plate above the table top, m (bottom plates stay at 0):
    gen.base.min_height/max_height, rss_train.yaml:59-60 (the paper: U(0.0, 0.15))."""
    shared_plate_height: bool = True
    """One elevation per scene for all its top plates (the authors' gen_base.py:286-290
    draws one height per scene); False: one per plate (the paper's "x 6")."""
    ceiling_height: Range = (0.3, 0.5)
    """Clearance of a nominal ceiling above the table top, before the platform rise, m."""
    gap_height: Range = (0.03, 0.05)
    """Clearance left above the object under a tight ceiling, m."""
    p_ceiling: float = 0.5
    """Probability that a scene has a ceiling (ceil_mask ~ B(p))."""
    p_wall: float = 0.5
    """Probability of each of the four walls (wall_mask ~ B(p)), before the ceiling's rules."""
    wall_height: Range = (0.05, 0.3)
    """Height of the walls of a scene without a ceiling above the table top, m, whatever the
    ceiling curriculum draws (gen.case.min/max_wall_height, rss_train.yaml:67-68, used for
    open scenes by gen_case.py:170-178; tight ceilings only where there is a ceiling,
    gen_both.py:158). Under a ceiling the walls reach it."""
    table_friction: Range = (0.2, 0.6)
    """Friction coefficient of every cuboid of the scene."""
    p_tight: float = 0.5
    """Probability of a tight ceiling rather than a nominal one; the curriculum raises it."""
    p_top_plate: float = 1.0 - 0.707
    """Probability that a planar plate is a top (elevated) plate rather than a bottom one:
    the authors raise a plate when U(0, 1) > p_high = 0.707 (gen_base.py:161,
    rss_train.yaml:57), so that about half of the 3 x 3 cells, each the higher of its two
    crossing plates, are raised; the paper says nothing (preset "paper": 0.5)."""
    plate_share_min: float = 0.1
    """Smallest share of an axis (after the ramps) that one planar plate takes."""
    table_origin: tuple[float, float] = (0.5, 0.0)
    """World xy of the table's centre at table_pos = 0, m; the robot stands at the world
    origin looking along +x."""
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
        for name in ("plate_height", "gap_height", "table_friction", "wall_height"):
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


SCENE_PRESETS: dict[str, SceneConfig] = {
    "paper": SceneConfig(
        table_pos_z=(0.1, 0.8), plate_height=(0.0, 0.15), shared_plate_height=False, p_top_plate=0.5
    ),
}
"""Named scene variants: the paper's Table tab:env-param where the authors' code differs."""
