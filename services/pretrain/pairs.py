"""One contact pair (paper appendix "Contact dataset generation"): two shapes (library objects
or scene cuboids) at random SE(3) poses, moved into touch, perturbed by a little Gaussian
noise so they either clip into each other or narrowly miss, then sampled into surface clouds
whose points are labelled by whether they lie inside the other shape's convex parts.

Consumes a numpy Generator and a `PairConfig`; produces a `ContactPair` of float32 clouds in
one shared frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from hamnet.pretrain.config import PairConfig
from hamnet.pretrain.convex import ConvexPart, convex_part, inside, overlap, touch_distance
from hamnet.runtime.errors import ConfigError
from hamnet.sim import quaternion
from hamnet.sim.objects.config import ObjectLibraryConfig, ShapeConfig
from hamnet.sim.objects.library import ObjectSet
from hamnet.sim.objects.mesh import Mesh, box_mesh, sample_surface
from hamnet.sim.objects.shapes import generate
from hamnet.sim.scene import sample_scenes

CUBOID = "cuboid"
"""Kind of a scene cuboid (the library's kinds name the others)."""
MAX_DIRECTIONS = 16
"""Directions tried before giving up on a pair of shapes (a line can miss two hollow
shapes, e.g. through a mug's handle; one try is the norm)."""


@dataclass(frozen=True, eq=False)
class Solid:
    """A shape in its own frame: its surface and the convex parts that fill it."""

    mesh: Mesh
    parts: tuple[ConvexPart, ...]
    kind: str


@dataclass(frozen=True, eq=False)
class ContactPair:
    """Two labelled surface clouds in one frame."""

    points_a: np.ndarray
    """(P, 3) float32, m."""
    points_b: np.ndarray
    """(P, 3) float32, m."""
    labels_a: np.ndarray
    """(P,) bool: the point of a lies inside b."""
    labels_b: np.ndarray
    """(P,) bool: the point of b lies inside a."""
    colliding: bool
    """The solids interpenetrate (exact, on the convex parts; clouds may miss a shallow one)."""
    kind_a: str
    kind_b: str


@lru_cache(maxsize=2)
def imported(folder: Path, shapes: ShapeConfig) -> ObjectSet:
    """The meshes of `folder` as library objects, once per process (the import is cached on
    disk too).

    Raises:
        ConfigError: the folder holds no mesh that imports.
    """
    objects = ObjectSet.from_folder(folder, ObjectLibraryConfig(shapes=shapes))
    if not len(objects):
        raise ConfigError(f"--pair.meshes {folder}: no mesh file there imports")
    return objects


def library_solid(rng: np.random.Generator, config: PairConfig) -> Solid:
    """A library object at a log-uniform scale: an imported mesh with chance `mesh_share`
    when `meshes` is given, else a procedural object of a random kind."""
    if config.meshes is not None and rng.random() < config.mesh_share:
        objects = imported(Path(config.meshes), config.shapes)
        asset = objects[int(rng.integers(len(objects)))]
        mesh, pieces, kind = asset.mesh, asset.parts, f"mesh:{asset.name}"
    else:
        kind = str(rng.choice(config.shapes.kinds))
        shape = generate(kind, rng, config.shapes)
        mesh, pieces = shape.mesh, shape.parts
    scale = float(np.exp(rng.uniform(*np.log(config.scale))))
    parts = tuple(convex_part(p.scaled(scale)) for p in pieces)
    return Solid(mesh.scaled(scale), parts, kind)


def cuboid_solid(rng: np.random.Generator, config: PairConfig) -> Solid:
    """One active cuboid (table, plate, ramp, wall or ceiling) of a sampled scene."""
    scene = sample_scenes(rng, rng.uniform(*config.shapes.extent, size=1), config.scene)
    half = scene.half_extent[0, rng.choice(np.flatnonzero(scene.active[0]))]  # (3,), m
    mesh = box_mesh(-half, half)
    return Solid(mesh, (convex_part(mesh),), CUBOID)


def random_solid(rng: np.random.Generator, config: PairConfig) -> Solid:
    """A scene cuboid with probability `cuboid_share`, else a library object."""
    return (
        cuboid_solid(rng, config)
        if rng.random() < config.cuboid_share
        else library_solid(rng, config)
    )


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """(3, 3) rotation uniform over SO(3) (a normalised Gaussian quaternion)."""
    q = rng.normal(size=4)
    return quaternion.to_matrix(q / np.linalg.norm(q))


def small_rotation(rng: np.random.Generator, std: float) -> np.ndarray:
    """(3, 3) rotation by a Gaussian axis-angle vector of `std` rad per component."""
    vector = rng.normal(scale=std, size=3) if std > 0 else np.zeros(3)
    angle = float(np.linalg.norm(vector))
    axis = vector / angle if angle > 0 else np.array([1.0, 0.0, 0.0])
    return quaternion.to_matrix(quaternion.from_axis_angle(axis, np.array(angle)))


def _posed(solid: Solid, rotation: np.ndarray, translation: np.ndarray) -> tuple[ConvexPart, ...]:
    return tuple(p.posed(rotation, translation) for p in solid.parts)


def touching_offset(
    rng: np.random.Generator, a: tuple[ConvexPart, ...], b: tuple[ConvexPart, ...]
) -> np.ndarray:
    """(3,) translation of b (posed at the origin like a) that makes the two just touch,
    along a random direction through both centres (see `convex.touch_distance`)."""
    for _ in range(MAX_DIRECTIONS):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        distance = touch_distance(a, b, direction)
        if distance is not None:
            return distance * direction
    raise RuntimeError(f"no direction of {MAX_DIRECTIONS} brought the shapes into touch")


def sample_pair(rng: np.random.Generator, config: PairConfig) -> ContactPair:
    """Draw one labelled contact pair (see the module docstring)."""
    solid_a, solid_b = random_solid(rng, config), random_solid(rng, config)
    rotation_a, rotation_b = random_rotation(rng), random_rotation(rng)
    parts_a = _posed(solid_a, rotation_a, np.zeros(3))
    offset_b = touching_offset(rng, parts_a, _posed(solid_b, rotation_b, np.zeros(3)))
    # The perturbation: B's pose jittered about its own centre.
    rotation_b = small_rotation(rng, config.perturb_rotation) @ rotation_b
    offset_b = offset_b + rng.normal(scale=config.perturb_translation, size=3)
    parts_b = _posed(solid_b, rotation_b, offset_b)
    local_a = sample_surface(solid_a.mesh, config.num_points, rng)  # (P, 3), own frame
    local_b = sample_surface(solid_b.mesh, config.num_points, rng)
    points_a, points_b = local_a @ rotation_a.T, local_b @ rotation_b.T + offset_b  # (P, 3)
    shift = rng.uniform(-config.position_range, config.position_range, size=3) - offset_b / 2
    return ContactPair(
        points_a=(points_a + shift).astype(np.float32),
        points_b=(points_b + shift).astype(np.float32),
        labels_a=inside(points_a, parts_b),
        labels_b=inside(points_b, parts_a),
        colliding=overlap(parts_a, parts_b),
        kind_a=solid_a.kind,
        kind_b=solid_b.kind,
    )
