"""Benchmark domains built like furniture: cabinet, top of cabinet, drawer and flat table
(paper, Sec. "Simulated Benchmark in Realistic Domains", Table tab:real-result).

Each builder has the signature of `scene.sample_scenes`: (rng, object_height (B,), config)
-> `SceneBatch`. The paper's digital twins come from CAD and NeRF scans that are not
public, so every dimension below is ours, chosen to pose the constraint the paper names for
the domain with furniture of everyday size; each shape's docstring says which. Frame: the
robot's base at the world origin looking along +x, the floor at `FLOOR_Z`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hamnet.sim.domains.fixture import Segments, assemble, ceiling_clearance, prepare
from hamnet.sim.scene import SceneBatch
from hamnet.sim.scene_config import FLOOR_Z, SceneConfig


@dataclass(frozen=True)
class CabinetShape:
    """The "cabinet": the object on the bottom shelf of a cupboard open towards the robot,
    under its top board, between its sides and before its back (Fig. 1a: the robot "must
    reach and maneuver the object while avoiding the ceiling"). Our choice: a 60 cm wide,
    35 cm deep kitchen module whose shelf is 45 cm above the floor, just above the robot's
    base, with 30 cm under the top board."""

    front_x: float = 0.35
    """x of the open front, m."""
    depth: float = 0.35
    """Inside depth from the front to the back board, m."""
    width: float = 0.60
    """Inside width between the sides, m."""
    shelf_z: float = 0.05
    """World z of the shelf's top, m (0.45 m above the floor)."""
    clearance: float = 0.30
    """Shelf to the top board's underside, m; raised for a taller object
    (`fixture.ceiling_clearance`), which never happens for the default library (<= 0.2 m)."""
    board: float = 0.02
    """Thickness of sides, back and top, m."""


@dataclass(frozen=True)
class SlabShape:
    """A domain that is one top surface, open above: the top of a cabinet, a flat table."""

    front_x: float
    """x of the front edge, m."""
    depth: float
    """Depth along x, m."""
    width: float
    """Width along y, m."""
    top_z: float
    """World z of the top, m."""


@dataclass(frozen=True)
class DrawerShape:
    """The "drawer": the object in a drawer pulled out of a chest of drawers, walls all
    round, the chest above the drawer's back part as a ceiling (the paper lists the drawer
    among domains with walls, appendix "Failure Modes"). Our choice: a 40 x 44 cm drawer,
    10 cm deep, pulled out 25 cm; its bottom 0.3 m above the floor. The drawer and the
    chest below it are one block down to the floor (the space under the pulled-out part
    is filled), a simplification of ours."""

    front_x: float = 0.30
    """x of the drawer's inside front, m."""
    depth: float = 0.40
    """Inside depth of the drawer, m."""
    width: float = 0.44
    """Inside width of the drawer, m."""
    floor_z: float = -0.10
    """World z of the drawer's bottom, m."""
    wall_height: float = 0.10
    """Height of the drawer's walls above its bottom, m."""
    wall: float = 0.015
    """Thickness of the drawer's walls, m."""
    pulled_out: float = 0.25
    """Inside length of the drawer out of the chest, m; the rest is under the chest."""
    clearance: float = 0.14
    """Drawer bottom to the chest's underside, m (4 cm over the walls for the runners);
    raised for a taller object (`fixture.ceiling_clearance`)."""
    chest_top_z: float = 0.35
    """World z of the chest's top, m (0.75 m above the floor)."""
    side: float = 0.02
    """Thickness of the chest's sides and back, m."""


CABINET = CabinetShape()
CABINET_TOP = SlabShape(front_x=0.35, depth=0.35, width=0.50, top_z=0.40)
"""The "top of cabinet": the object on top of a tall cabinet, open above (Fig. 1i: the
robot "must consider its kinematics while manipulating the object on a high shelf").
Our choice: a 50 x 35 cm top 0.8 m above the floor, 0.4 m above the robot's base and
about its shoulder's height, so reaching over the far edge nears the arm's limit."""
DRAWER = DrawerShape()
FLAT = SlabShape(front_x=0.30, depth=0.45, width=0.60, top_z=0.0)
"""The "flat" domain: a plain table. Our choice: 45 x 60 cm at the height of the robot's
base (0.4 m above the floor), in the middle of the procedural tables' range."""


def _plain(x: tuple[float, float], y: tuple[float, float]) -> tuple[Segments, Segments]:
    """The profile of one flat rectangle `x` by `y` (nominal, m) at the support's top."""
    return Segments(x, (0.0,)), Segments(y, (0.0,))


def cabinet(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B cabinets (`CabinetShape`): shelf, back, sides and top board."""
    height, config, fixture = prepare(rng, object_height, config)
    s = CABINET
    x, y = (s.front_x, s.front_x + s.depth), (-s.width / 2, s.width / 2)
    ceiling = s.shelf_z + ceiling_clearance(s.clearance, height, config)  # (B,), m
    t = s.board
    parts = [
        fixture.box((x[0], y[0], FLOOR_Z), (x[1], y[1], s.shelf_z)),  # shelf, carcass below
        *fixture.walls(x, y, (FLOOR_Z, ceiling), t)[1:],  # back, right and left
        fixture.box((x[0], y[0] - t, ceiling), (x[1] + t, y[1] + t, ceiling + t)),  # top
    ]
    profile = fixture.profile(*_plain(x, y))
    ceiling_z = fixture.point(0.0, 0.0, ceiling)[:, 2]
    return assemble(fixture, parts, profile, height, config, ceiling_z=ceiling_z)


def cabinet_top(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B tall cabinets (`CABINET_TOP`) with the object on top."""
    return _slab(rng, object_height, config, CABINET_TOP)


def drawer(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B open drawers (`DrawerShape`): bottom, four walls, and the chest's top part, sides
    and back around the drawer's back part."""
    height, config, fixture = prepare(rng, object_height, config)
    s = DRAWER
    x, y = (s.front_x, s.front_x + s.depth), (-s.width / 2, s.width / 2)
    ceiling = s.floor_z + ceiling_clearance(s.clearance, height, config)  # (B,), m
    chest_x = (s.front_x + s.pulled_out, x[1] + s.wall + s.side)
    outer = s.wall + s.side  # the chest's sides stand beside the drawer's walls
    parts = [
        fixture.box((x[0], y[0], FLOOR_Z), (x[1], y[1], s.floor_z)),  # bottom
        *fixture.walls(x, y, (FLOOR_Z, s.floor_z + s.wall_height), s.wall),
        fixture.box((chest_x[0], y[0] - outer, ceiling), (chest_x[1], y[1] + outer, s.chest_top_z)),
        fixture.box((chest_x[0], y[0] - outer, FLOOR_Z), (chest_x[1], y[0] - s.wall, ceiling)),
        fixture.box((chest_x[0], y[1] + s.wall, FLOOR_Z), (chest_x[1], y[1] + outer, ceiling)),
        fixture.box((x[1] + s.wall, y[0] - s.wall, FLOOR_Z), (chest_x[1], y[1] + s.wall, ceiling)),
    ]
    ceiling_z = fixture.point(0.0, 0.0, ceiling)[:, 2]
    profile = fixture.profile(*_plain(x, y))
    return assemble(fixture, parts, profile, height, config, ceiling_z=ceiling_z)


def flat(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B plain tables (`FLAT`)."""
    return _slab(rng, object_height, config, FLAT)


def _slab(
    rng: np.random.Generator,
    object_height: np.ndarray,
    config: SceneConfig | None,
    shape: SlabShape,
) -> SceneBatch:
    """B single slabs of `shape`, from the floor to their top."""
    height, config, fixture = prepare(rng, object_height, config)
    x, y = (shape.front_x, shape.front_x + shape.depth), (-shape.width / 2, shape.width / 2)
    parts = [fixture.box((x[0], y[0], FLOOR_Z), (x[1], y[1], shape.top_z))]
    return assemble(fixture, parts, fixture.profile(*_plain(x, y)), height, config)
