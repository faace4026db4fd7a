"""Procedural object shapes, generated deterministically from a numpy Generator.

Stands in for DexGraspNet, which is not available offline: boxes, cylinders,
superellipsoids, random convex polytopes, and compounds of boxes and a cylinder (an L, a T,
a mug with a handle). Every shape is a watertight mesh plus its exact convex parts (the
mesh itself for convex shapes, the primitives for compounds, so no approximate
decomposition is needed), with every side of its bounding box inside `ShapeConfig.extent`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh

from hamnet.sim.objects.config import ShapeConfig
from hamnet.sim.objects.mesh import Mesh, box_mesh, center_of_mass, convex_hull, union


@dataclass(frozen=True, eq=False)
class Shape:
    """A closed surface and convex pieces that together fill it."""

    mesh: Mesh
    """Watertight surface, centred at its centre of mass."""
    parts: tuple[Mesh, ...]
    """Convex pieces in the same frame; they may overlap."""


ShapeFn = Callable[[np.random.Generator, ShapeConfig], Shape]
SHAPES: dict[str, ShapeFn] = {}
"""Shape generators by kind; `ShapeConfig.kinds` names a subset."""


def shape(kind: str) -> Callable[[ShapeFn], ShapeFn]:
    """Register a generator under `kind`."""

    def register(fn: ShapeFn) -> ShapeFn:
        SHAPES[kind] = fn
        return fn

    return register


def generate(kind: str, rng: np.random.Generator, config: ShapeConfig) -> Shape:
    """A shape of `kind`, centred at its centre of mass."""
    raw = SHAPES[kind](rng, config)
    offset = -center_of_mass(raw.mesh)  # (3,)
    return Shape(raw.mesh.translated(offset), tuple(p.translated(offset) for p in raw.parts))


def _fit_extents(mesh: Mesh, extents: np.ndarray) -> Mesh:
    """Stretch a convex mesh per axis so its bounding box is exactly `extents` (3,)."""
    low, high = mesh.bounds
    return Mesh((mesh.vertices - (low + high) / 2) * (extents / (high - low)), mesh.faces)


def _convex(mesh: Mesh) -> Shape:
    return Shape(mesh, (mesh,))


@shape("box")
def box(rng: np.random.Generator, config: ShapeConfig) -> Shape:
    extents = rng.uniform(*config.extent, size=3)  # (3,), m
    return _convex(box_mesh(-extents / 2, extents / 2))


@shape("cylinder")
def cylinder(rng: np.random.Generator, config: ShapeConfig) -> Shape:
    diameter, height = rng.uniform(*config.extent, size=2)
    solid = trimesh.creation.cylinder(
        radius=diameter / 2, height=height, sections=config.cylinder_sections
    )
    return _convex(Mesh.from_trimesh(solid))


@shape("superellipsoid")
def superellipsoid(rng: np.random.Generator, config: ShapeConfig) -> Shape:
    """Barr's superellipsoid: e -> 0 gives a box, e = 1 an ellipsoid, e -> 2 an octahedron."""
    extents = rng.uniform(*config.extent, size=3)  # (3,), m
    e1, e2 = rng.uniform(*config.superellipsoid_exponents, size=2)
    directions = trimesh.creation.icosphere(config.superellipsoid_subdivisions).vertices  # (V, 3)
    x, y, z = np.abs(directions).T
    # The implicit function is homogeneous of degree 2/e1, so each unit direction reaches the
    # surface at r = F(direction)^(-e1/2); the hull keeps the faceted result exactly convex.
    implicit = (x ** (2 / e2) + y ** (2 / e2)) ** (e2 / e1) + z ** (2 / e1)
    points = directions * implicit[:, None] ** (-e1 / 2)  # (V, 3), unit semi-axes
    return _convex(_fit_extents(convex_hull(points), extents))


@shape("polytope")
def polytope(rng: np.random.Generator, config: ShapeConfig) -> Shape:
    """Convex hull of random points in a ball, stretched to a random bounding box."""
    count = int(rng.integers(config.polytope_points[0], config.polytope_points[1] + 1))
    directions = rng.normal(size=(count, 3))  # (N, 3)
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    points = directions * rng.uniform(0.5, 1.0, size=(count, 1))  # (N, 3)
    extents = rng.uniform(*config.extent, size=3)  # (3,), m
    return _convex(_fit_extents(convex_hull(points), extents))


def _compound(parts: list[Mesh]) -> Shape:
    return Shape(union(parts), tuple(parts))


@shape("l_shape")
def l_shape(rng: np.random.Generator, config: ShapeConfig) -> Shape:
    """Two boxes meeting at a right angle in the x-z plane."""
    low, high = config.extent
    length, height = rng.uniform(2 * low, high, size=2)  # along x and z, m
    depth = rng.uniform(low, high)  # along y, m
    foot = rng.uniform(low, height / 2)  # thickness of the horizontal bar, m
    leg = rng.uniform(low, length / 2)  # thickness of the vertical bar, m
    y = depth / 2
    return _compound(
        [
            box_mesh(np.array([0, -y, 0]), np.array([length, y, foot])),
            box_mesh(np.array([0, -y, 0]), np.array([leg, y, height])),
        ]
    )


@shape("t_shape")
def t_shape(rng: np.random.Generator, config: ShapeConfig) -> Shape:
    """A bar on top of a centred stem, in the x-z plane."""
    low, high = config.extent
    width, height = rng.uniform(2 * low, high, size=2)
    depth = rng.uniform(low, high)
    bar = rng.uniform(low, height / 2)
    stem = rng.uniform(low, width / 2)
    y = depth / 2
    return _compound(
        [
            box_mesh(np.array([-width / 2, -y, height - bar]), np.array([width / 2, y, height])),
            box_mesh(np.array([-stem / 2, -y, 0]), np.array([stem / 2, y, height])),
        ]
    )


@shape("mug")
def mug(rng: np.random.Generator, config: ShapeConfig) -> Shape:
    """A solid cylinder with a C-shaped handle of three boxes (the handle leaves a hole)."""
    low, high = config.extent
    diameter = rng.uniform(low, 0.6 * high)
    height = rng.uniform(low, high)
    radius = diameter / 2
    reach = rng.uniform(0.15, 0.3) * diameter  # handle's reach beyond the body, m
    bar = 0.15 * diameter  # handle bar thickness, m
    y = rng.uniform(0.15, 0.25) * diameter  # half depth of the handle, m
    inner, outer = 0.75 * radius, radius + reach  # arms start inside the body
    bottom, top = 0.2 * height, 0.8 * height
    body = trimesh.creation.cylinder(
        radius=radius, height=height, sections=config.cylinder_sections
    )
    return _compound(
        [
            Mesh.from_trimesh(body).translated(np.array([0, 0, height / 2])),
            box_mesh(np.array([inner, -y, top - bar]), np.array([outer, y, top])),
            box_mesh(np.array([inner, -y, bottom]), np.array([outer, y, bottom + bar])),
            box_mesh(np.array([outer - bar, -y, bottom]), np.array([outer, y, top])),
        ]
    )
