"""Draws of a procedural scene's parameters (paper, "Procedural domain and curriculum
generation"), batched: the interior (plate elevations, ramp tilts, plate sizes) and the case
(walls, ceiling, the nominal or tight height they reach).

Consumes a `numpy.random.Generator` and a `SceneConfig`; produces `Interior` and `Case`
arrays that `scene.sample_scenes` turns into cuboid slots, standing regions and the EnvCode.
Kept apart from those so the distributions read on their own. Shapes: B environments.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hamnet.sim.scene_config import SceneConfig


class Interior(NamedTuple):
    """Plates and ramps along the two table axes (x, y)."""

    height: np.ndarray
    """(B, 2, 3) planar plate elevation above the table top, m."""
    angle: np.ndarray
    """(B, 2, 2) ramp tilt from the vertical, rad."""
    edges: np.ndarray
    """(B, 2, 6) segment boundaries from the table centre, m."""


class Case(NamedTuple):
    """Walls and ceiling around the table."""

    height: np.ndarray
    """(B,) ceiling clearance above the table top (walls reach it), m."""
    wall_height: np.ndarray
    """(B,) wall top above the table top, m: `height` under a ceiling."""
    wall: np.ndarray
    """(B, 4) bool, order front, back, right, left."""
    ceiling: np.ndarray
    """(B,) bool."""
    tight: np.ndarray
    """(B,) bool."""


def sample_interior(rng: np.random.Generator, extent: np.ndarray, config: SceneConfig) -> Interior:
    """Plate elevations, ramp tilts and the plate sizes that fit them on the table.

    Each planar plate is a top plate with probability p_top_plate, raised by U(plate_height),
    one draw per scene (`shared_plate_height`) or per plate; bottom plates lie at the table
    top. A ramp's horizontal run is |rise| * tan(tilt), and the three plates share what the
    two runs leave of the axis, so plates and ramps tile the table exactly.

    Args:
        rng: source of randomness.
        extent: (B, 2) table size along x, y, m.
        config: distributions.
    Returns:
        The B interiors.
    """
    num_envs = len(extent)
    is_top = rng.random((num_envs, 2, 3)) < config.p_top_plate
    draws = (num_envs, 1, 1) if config.shared_plate_height else (num_envs, 2, 3)
    height = is_top * rng.uniform(*config.plate_height, size=draws)  # (B, 2, 3), m
    angle = rng.uniform(*config.ramp_angle, size=(num_envs, 2, 2))  # (B, 2, 2), rad
    share = rng.dirichlet(np.ones(3), size=(num_envs, 2))  # (B, 2, 3), sums to 1
    share = config.plate_share_min + (1.0 - 3.0 * config.plate_share_min) * share
    run = np.abs(np.diff(height, axis=-1)) * np.tan(angle)  # (B, 2, 2), m
    plate = share * (extent - run.sum(axis=-1))[..., None]  # (B, 2, 3), m
    lengths = interleave(plate, run)  # (B, 2, 5): plate, ramp, plate, ramp, plate
    edges = (
        np.concatenate([np.zeros((num_envs, 2, 1)), np.cumsum(lengths, axis=-1)], axis=-1)
        - extent[..., None] / 2
    )  # (B, 2, 6), from the table centre
    edges[..., -1] = extent / 2  # exact far edge despite rounding in the sum
    return Interior(height=height, angle=angle, edges=edges)


def sample_case(
    rng: np.random.Generator, object_height: np.ndarray, rise: np.ndarray, config: SceneConfig
) -> Case:
    """Walls and ceiling: masks, the nominal/tight choice and the height they reach.

    A ceiling opens the front wall (the robot's way in) and keeps at least one of the other
    three walls to carry it; its walls reach it. Without a ceiling the walls are
    U(wall_height) high, whatever the tight/nominal draw.

    Args:
        rng: source of randomness.
        object_height: (B,) height of each environment's object, m; a tight ceiling leaves
            a gap of U(gap_height) above it.
        rise: (B,) the highest platform, m, which lifts the ceiling so objects stay under it.
        config: distributions.
    Returns:
        The B cases.
    """
    num_envs = len(object_height)
    ceiling = rng.random(num_envs) < config.p_ceiling
    tight = rng.random(num_envs) < config.p_tight
    nominal = rng.uniform(*config.ceiling_height, size=num_envs)  # (B,), m
    gap = rng.uniform(*config.gap_height, size=num_envs)  # (B,), m
    wall = rng.random((num_envs, 4)) < config.p_wall  # (B, 4)
    support = rng.integers(1, 4, size=num_envs)  # (B,) wall raised if a ceiling has none
    wall[:, 0] &= ~ceiling
    unsupported = ceiling & ~wall[:, 1:].any(axis=-1)
    wall[unsupported, support[unsupported]] = True
    open_walls = rng.uniform(*config.wall_height, size=num_envs)  # (B,), m
    height = np.where(tight, object_height + gap, nominal) + rise
    wall_height = np.where(ceiling, height, open_walls)
    return Case(height=height, wall_height=wall_height, wall=wall, ceiling=ceiling, tight=tight)


def interleave(plate: np.ndarray, ramp: np.ndarray) -> np.ndarray:
    """Segment values (..., 5) in axis order from plate (..., 3) and ramp (..., 2) values."""
    return np.stack(
        [plate[..., 0], ramp[..., 0], plate[..., 1], ramp[..., 1], plate[..., 2]], axis=-1
    )
