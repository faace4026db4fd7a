"""Triangle meshes as plain arrays, and the geometry the library needs from them.

A `Mesh` is what crosses module boundaries (and the cache): float64 vertices in metres and
int32 faces. trimesh does the heavy lifting (volume, centre of mass, inertia, convex hulls)
behind the few functions here, so the rest of the library never holds a `trimesh.Trimesh`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
import trimesh


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh."""

    vertices: np.ndarray
    """(V, 3) float64, m."""
    faces: np.ndarray
    """(F, 3) int32, counter-clockwise seen from outside."""

    def __post_init__(self) -> None:
        vertices = np.ascontiguousarray(self.vertices, dtype=np.float64)
        faces = np.ascontiguousarray(self.faces, dtype=np.int32)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(
                f"need (V, 3) vertices and (F, 3) faces, got {vertices.shape}, {faces.shape}"
            )
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)

    @classmethod
    def from_trimesh(cls, mesh: trimesh.Trimesh) -> Mesh:
        return cls(np.asarray(mesh.vertices), np.asarray(mesh.faces))

    def to_trimesh(self) -> trimesh.Trimesh:
        return trimesh.Trimesh(self.vertices, self.faces, process=False)

    def translated(self, offset: np.ndarray) -> Mesh:
        """The mesh moved by `offset` (3,), m."""
        return Mesh(self.vertices + offset, self.faces)

    def scaled(self, scale: float) -> Mesh:
        """The mesh scaled uniformly about the origin."""
        return Mesh(self.vertices * scale, self.faces)

    def rotated(self, rotation: np.ndarray) -> Mesh:
        """The mesh rotated by the (3, 3) matrix `rotation` about the origin."""
        return Mesh(self.vertices @ rotation.T, self.faces)

    @property
    def volume(self) -> float:
        """Enclosed volume, m^3 (meaningful for a watertight mesh)."""
        return float(self.to_trimesh().volume)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned bounding box: min and max corner, m."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    def digest(self) -> str:
        """SHA-256 of the vertex and face bytes: a cache key for the geometry."""
        return hashlib.sha256(self.vertices.tobytes() + self.faces.tobytes()).hexdigest()


def box_mesh(low: np.ndarray, high: np.ndarray) -> Mesh:
    """Axis-aligned box between corners `low` and `high` (3,), m."""
    box = trimesh.creation.box(extents=np.asarray(high) - np.asarray(low))
    return Mesh.from_trimesh(box).translated((np.asarray(low) + np.asarray(high)) / 2)


def convex_hull(points: np.ndarray) -> Mesh:
    """Convex hull of (N, 3) points as a closed, outward-facing mesh."""
    return Mesh.from_trimesh(trimesh.convex.convex_hull(points))


def union(meshes: list[Mesh]) -> Mesh:
    """Boolean union of closed meshes (manifold3d): one watertight surface, no inner faces."""
    merged = trimesh.boolean.union([m.to_trimesh() for m in meshes], engine="manifold")
    return Mesh.from_trimesh(merged)


def center_of_mass(mesh: Mesh) -> np.ndarray:
    """(3,) centre of mass of the solid at uniform density, m."""
    return np.asarray(mesh.to_trimesh().center_mass, dtype=np.float64)


def unit_inertia(mesh: Mesh) -> np.ndarray:
    """(3, 3) inertia tensor per kg about the centre of mass at uniform density, m^2."""
    solid = mesh.to_trimesh()
    return np.asarray(solid.moment_inertia, dtype=np.float64) / float(solid.mass)


def is_convex(mesh: Mesh) -> bool:
    """Whether the closed mesh is convex (trimesh's edge test, float tolerance)."""
    return bool(mesh.to_trimesh().is_convex)


def triangle_areas(mesh: Mesh) -> np.ndarray:
    """(F,) area of each face, m^2."""
    a, b, c = (mesh.vertices[mesh.faces[:, i]] for i in range(3))  # (F, 3) each
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def sample_surface(mesh: Mesh, count: int, rng: np.random.Generator) -> np.ndarray:
    """Points drawn uniformly over the surface (faces picked by area).

    Args:
        mesh: the surface.
        count: number of points N (the object cloud uses 512).
        rng: source of randomness.
    Returns:
        (N, 3) float64 points on the surface, m.
    """
    areas = triangle_areas(mesh)  # (F,)
    face = rng.choice(len(areas), size=count, p=areas / areas.sum())  # (N,)
    u, v = rng.random((2, count))  # (N,) each
    flip = u + v > 1.0  # reflect into the triangle so the density stays uniform
    u, v = np.where(flip, 1.0 - u, u), np.where(flip, 1.0 - v, v)
    a, b, c = (mesh.vertices[mesh.faces[face, i]] for i in range(3))  # (N, 3) each
    return a + u[:, None] * (b - a) + v[:, None] * (c - a)
