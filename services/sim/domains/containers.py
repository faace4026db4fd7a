"""Benchmark domains built like containers: sink, basket, circular bin, suitcase and grill
(paper, Sec. "Simulated Benchmark in Realistic Domains", Table tab:real-result).

Each builder has the signature of `scene.sample_scenes`: (rng, object_height (B,), config)
-> `SceneBatch`. The paper's digital twins come from CAD and NeRF scans that are not
public, so every dimension below is ours, chosen to pose the constraint the paper names for
the domain with containers of everyday size; each shape's docstring says which. The sink
and the grill keep start and goal apart (`SceneBatch.region_start`, `region_goal`): in the
basin and on the counter, or on either side of the bars, each way round with even odds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hamnet.sim.domains.fixture import (
    Fixture,
    Part,
    Segments,
    assemble,
    cells,
    either,
    prepare,
)
from hamnet.sim.scene import SceneBatch
from hamnet.sim.scene_config import FLOOR_Z, SceneConfig

Span = tuple[float, float]
"""Nominal (low, high) coordinates along one axis, m."""


@dataclass(frozen=True)
class SinkShape:
    """The "sink": a basin let into a counter; the object starts in the basin with its goal
    on the counter, or the other way (Fig. 1e: the robot "must first traverse the sink to
    contact under the crab, lift it across the sink wall, then reorient" it). Our choice:
    a 30 x 40 cm basin, 12 cm deep (a shallow bar sink), in the right part of a 55 x 90 cm
    counter at the robot's base height, leaving 43 cm of counter on its left."""

    counter_x: Span = (0.25, 0.80)
    """Front and back edges of the counter, m."""
    counter_y: Span = (-0.45, 0.45)
    """Right and left edges of the counter, m."""
    counter_z: float = 0.0
    """World z of the counter's top, m."""
    basin_x: Span = (0.38, 0.68)
    """Front and back of the basin's inside, m."""
    basin_y: Span = (-0.38, 0.02)
    """Right and left of the basin's inside, m."""
    depth: float = 0.12
    """Counter top to the basin's bottom, m."""


@dataclass(frozen=True)
class BasketShape:
    """The "basket": low walls all round the object (Fig. 1b, c: the robot "must circumvent
    walls to access the object"). Our choice: a 34 x 48 cm storage basket with 10 cm walls,
    its bottom at the robot's base height."""

    inside_x: Span = (0.38, 0.72)
    """Front and back of the inside, m."""
    inside_y: Span = (-0.24, 0.24)
    """Right and left of the inside, m."""
    floor_z: float = 0.0
    """World z of the bottom, m."""
    wall_height: float = 0.10
    """Walls above the bottom, m."""
    wall: float = 0.012
    """Wall thickness, m."""


@dataclass(frozen=True)
class CircularBinShape:
    """The "circular bin": a round bin whose wall is a regular polygon of `sides` cuboids
    (the paper counts it among the curved surfaces the policy adapts to, Sec.
    "Limitations"). Our choice: 44 cm inside, 12 cm high, 12 sides; objects start and end
    within the square inscribed in the inside circle."""

    centre: Span = (0.55, 0.0)
    """World xy of the bin's axis, m."""
    radius: float = 0.22
    """Distance from the axis to the inside of each side, m."""
    wall: float = 0.012
    """Wall thickness, m."""
    height: float = 0.12
    """Walls above the bottom, m."""
    sides: int = 12
    """Wall cuboids around the polygon (15 slots are free after the bottom)."""
    floor_z: float = 0.0
    """World z of the bottom, m."""


@dataclass(frozen=True)
class SuitcaseShape:
    """The "suitcase": an open suitcase on a bench, the shell's low walls all round and its
    lid upright behind (Table tab:real-result). Our choice: a 35 x 50 cm shell, 8 cm deep,
    its bottom 0.35 m above the floor; the lid 3 cm thick and as tall as the shell is long
    (39 cm), standing on the back wall."""

    inside_x: Span = (0.35, 0.70)
    """Front and back of the shell's inside, m."""
    inside_y: Span = (-0.25, 0.25)
    """Right and left of the shell's inside, m."""
    floor_z: float = -0.05
    """World z of the shell's bottom, m."""
    wall_height: float = 0.08
    """Shell walls above the bottom, m."""
    wall: float = 0.02
    """Shell wall thickness, m."""
    lid: float = 0.03
    """Lid thickness, m."""


@dataclass(frozen=True)
class GrillShape:
    """The "grill": grill bars across a tray, the start on one side and the goal on the
    other (Fig. 1d: the robot "must move the object over a barrier"; the paper counts the
    grill among uneven surfaces, Sec. "Limitations"). Our choice: a 35 x 64 cm tray with a
    4 cm rim at the robot's base height, three 1.5 cm bars, 3 cm high at a 5 cm pitch,
    running along x through its middle."""

    inside_x: Span = (0.35, 0.70)
    """Front and back of the tray's inside, m."""
    inside_y: Span = (-0.32, 0.32)
    """Right and left of the tray's inside, m."""
    floor_z: float = 0.0
    """World z of the tray's bottom, m."""
    rim_height: float = 0.04
    """Rim above the bottom, m."""
    rim: float = 0.01
    """Rim thickness, m."""
    bars: int = 3
    """Bars of the barrier."""
    bar_pitch: float = 0.05
    """Distance between neighbouring bars' axes, m."""
    bar_width: float = 0.015
    """Width of a bar, m."""
    bar_height: float = 0.03
    """Height of a bar above the bottom, m."""


SINK = SinkShape()
BASKET = BasketShape()
CIRCULAR_BIN = CircularBinShape()
SUITCASE = SuitcaseShape()
GRILL = GrillShape()

P_START_FIRST = 0.5
"""Probability that a sink's start is in its basin (else on its counter) and that a grill's
start is on its right side (else its left): each way round equally often."""


def sink(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B sinks (`SinkShape`): the counter's block down to the basin's bottom, and the four
    strips of counter around the basin."""
    height, config, fixture = prepare(rng, object_height, config)
    s = SINK
    (cx0, cx1), (cy0, cy1), (bx0, bx1), (by0, by1) = s.counter_x, s.counter_y, s.basin_x, s.basin_y
    bottom, top = s.counter_z - s.depth, s.counter_z
    parts = [
        fixture.box((cx0, cy0, FLOOR_Z), (cx1, cy1, bottom)),  # basin bottom and below
        fixture.box((cx0, cy0, bottom), (bx0, cy1, top)),  # front strip
        fixture.box((bx1, cy0, bottom), (cx1, cy1, top)),  # back strip
        fixture.box((bx0, cy0, bottom), (bx1, by0, top)),  # right rim
        fixture.box((bx0, by1, bottom), (bx1, cy1, top)),  # left counter
    ]
    counter = (s.depth, 0.0, s.depth)
    profile = fixture.profile(
        Segments((cx0, bx0, bx1, cx1), counter), Segments((cy0, by0, by1, cy1), counter)
    )
    basin = cells((1, 1))
    return _either_way(rng, fixture, parts, profile, height, config, basin, ~basin)


def basket(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B baskets (`BasketShape`): the bottom and four walls."""
    height, config, fixture = prepare(rng, object_height, config)
    return assemble(fixture, _shell(fixture, BASKET), _inside(fixture, BASKET), height, config)


def suitcase(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B open suitcases (`SuitcaseShape`): the shell's bottom and walls, the lid upright on
    its back wall, flush with the inside so it clears any object the shell holds."""
    height, config, fixture = prepare(rng, object_height, config)
    s = SUITCASE
    (x0, x1), (y0, y1) = s.inside_x, s.inside_y
    rim = s.floor_z + s.wall_height
    lid = fixture.box((x1, y0 - s.wall, rim), (x1 + s.lid, y1 + s.wall, rim + x1 - x0 + 2 * s.wall))
    return assemble(fixture, [*_shell(fixture, s), lid], _inside(fixture, s), height, config)


def _shell(fixture: Fixture, shape: BasketShape | SuitcaseShape) -> list[Part]:
    """A flat bottom down to the floor inside four walls from the floor to `wall_height`
    above the bottom."""
    (x0, x1), (y0, y1) = shape.inside_x, shape.inside_y
    top = shape.floor_z + shape.wall_height
    return [
        fixture.box((x0, y0, FLOOR_Z), (x1, y1, shape.floor_z)),
        *fixture.walls(shape.inside_x, shape.inside_y, (FLOOR_Z, top), shape.wall),
    ]


def _inside(
    fixture: Fixture, shape: BasketShape | SuitcaseShape
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The profile of the whole inside, one flat cell."""
    return fixture.profile(Segments(shape.inside_x, (0.0,)), Segments(shape.inside_y, (0.0,)))


def circular_bin(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B round bins (`CircularBinShape`): a square bottom and a polygon of wall cuboids
    standing on it, each turned to face the axis and long enough to close the corners."""
    height, config, fixture = prepare(rng, object_height, config)
    s = CIRCULAR_BIN
    (cx, cy), r, t = s.centre, s.radius, s.wall
    outer = r + t  # the outer polygon's apothem, m
    parts = [fixture.box((cx - outer, cy - outer, FLOOR_Z), (cx + outer, cy + outer, s.floor_z))]
    half = (t / 2, outer * math.tan(math.pi / s.sides), s.height / 2)
    for k in range(s.sides):
        angle = 2 * math.pi * k / s.sides
        centre = (cx + (r + t / 2) * math.cos(angle), cy + (r + t / 2) * math.sin(angle))
        parts.append(fixture.yawed((*centre, s.floor_z + s.height / 2), half, angle))
    inscribed = r / math.sqrt(2)  # half side of the square inside the inside circle, m
    profile = fixture.profile(
        Segments((cx - inscribed, cx + inscribed), (0.0,)),
        Segments((cy - inscribed, cy + inscribed), (0.0,)),
    )
    return assemble(fixture, parts, profile, height, config)


def grill(
    rng: np.random.Generator, object_height: np.ndarray, config: SceneConfig | None = None
) -> SceneBatch:
    """B grills (`GrillShape`): the tray's bottom, its bars and its rim."""
    height, config, fixture = prepare(rng, object_height, config)
    s = GRILL
    x, y = s.inside_x, s.inside_y
    parts = [fixture.box((x[0], y[0], FLOOR_Z), (x[1], y[1], s.floor_z))]
    for k in range(s.bars):
        axis = (k - (s.bars - 1) / 2) * s.bar_pitch  # y of the bar's axis, m
        lo = (x[0], axis - s.bar_width / 2, s.floor_z)
        parts.append(fixture.box(lo, (x[1], axis + s.bar_width / 2, s.floor_z + s.bar_height)))
    parts += fixture.walls(x, y, (FLOOR_Z, s.floor_z + s.rim_height), s.rim)
    band = (s.bars - 1) / 2 * s.bar_pitch + s.bar_width / 2  # half width of the bars, m
    across = Segments((y[0], -band, band, y[1]), (0.0, 0.0, 0.0), (0.0, s.bar_height, 0.0))
    profile = fixture.profile(Segments(x, (0.0,)), across)
    right, left = cells((0, 0)), cells((0, 2))
    return _either_way(rng, fixture, parts, profile, height, config, right, left)


def _either_way(
    rng: np.random.Generator,
    fixture: Fixture,
    parts: list[Part],
    profile: tuple[np.ndarray, np.ndarray, np.ndarray],
    height: np.ndarray,
    config: SceneConfig,
    first: np.ndarray,
    second: np.ndarray,
) -> SceneBatch:
    """The scenes with the start in the cells `first` and the goal in `second`, or the
    other way round, with probability `P_START_FIRST` per environment."""
    start_first = rng.random(fixture.num_envs) < P_START_FIRST  # (B,)
    return assemble(
        fixture,
        parts,
        profile,
        height,
        config,
        start_cells=either(start_first, first, second),
        goal_cells=either(start_first, second, first),
    )
