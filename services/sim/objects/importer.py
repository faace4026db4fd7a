"""Importing any folder of meshes (OBJ, STL, PLY, OFF, GLB) into the object library.

Each file is loaded with trimesh (a GLB scene is flattened into one mesh), cleaned, scaled
into the library's size range, decomposed into convex parts, centred at its centre of mass
and given stable poses; results are cached by the file's bytes and the build settings, so a
second import of an unchanged folder computes nothing. Files are never fetched: the folder
must already be on disk.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import trimesh

from hamnet.sim.objects.asset import ObjectAsset
from hamnet.sim.objects.build import cached, finish
from hamnet.sim.objects.cache import ObjectCache, cache_key
from hamnet.sim.objects.config import ObjectLibraryConfig
from hamnet.sim.objects.decompose import decompose
from hamnet.sim.objects.mesh import Mesh, center_of_mass, union

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".off", ".glb")
"""File types imported (matched case-insensitively)."""
UNIT_SCALES = (1.0, 0.01, 0.001)
"""Units tried in turn for a file's numbers: metres, centimetres, millimetres."""


def mesh_files(folder: Path) -> list[Path]:
    """Mesh files anywhere under `folder`, sorted, so a folder always imports the same way."""
    return sorted(
        p for p in Path(folder).rglob("*") if p.is_file() and p.suffix.lower() in MESH_SUFFIXES
    )


def unit_scale(longest: float, extent: tuple[float, float]) -> float:
    """Scale that puts a mesh's longest side `longest` inside `extent`, m.

    The first of m, cm, mm that fits is taken as the file's unit; if none fits (e.g. a mesh
    normalised to unit size), the longest side is clamped to the nearer end of the range.
    """
    low, high = extent
    for scale in UNIT_SCALES:
        if low <= longest * scale <= high:
            return scale
    return float(np.clip(longest, low, high)) / longest


def load_surface(path: Path, extent: tuple[float, float]) -> trimesh.Trimesh:
    """The file's mesh, cleaned (merged vertices, no degenerate faces, outward normals), scaled."""
    mesh = trimesh.load(path, force="mesh")
    if len(mesh.faces) < 4:
        raise ValueError("no closed surface in the file (fewer than 4 triangles)")
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    if not mesh.is_watertight:
        trimesh.repair.fill_holes(mesh)
    trimesh.repair.fix_normals(mesh)
    mesh.apply_scale(unit_scale(float(mesh.extents.max()), extent))
    return mesh


def _build(name: str, path: Path, config: ObjectLibraryConfig) -> ObjectAsset:
    loaded = load_surface(path, config.shapes.extent)
    surface = Mesh.from_trimesh(loaded)
    parts = decompose(surface, config.decomposition)
    if not loaded.is_watertight:
        # An open surface has no inside; the union of CoACD's pieces (CoACD remeshes its
        # input into a manifold first) is the closest closed surface.
        surface = union(list(parts))
    offset = -center_of_mass(surface)
    return finish(
        name,
        surface.translated(offset),
        tuple(p.translated(offset) for p in parts),
        str(path),
        config,
    )


def import_mesh(
    path: Path, config: ObjectLibraryConfig, cache: ObjectCache | None, name: str | None = None
) -> ObjectAsset:
    """One mesh file as a library object, from the cache when the file and settings are unchanged.

    Raises:
        UnstableObjectError: the object never came to rest stably.
        ValueError: the file holds no usable mesh.
    """
    path = Path(path)
    key = cache_key(
        path.read_bytes(),
        path.suffix.lower(),
        config.shapes.extent,
        config.decomposition,
        config.stability,
    )
    name = name or path.stem
    return cached(cache, key, lambda: _build(name, path, config), name=name, source=str(path))


def import_folder(
    folder: Path, config: ObjectLibraryConfig, cache: ObjectCache | None
) -> list[ObjectAsset]:
    """Every mesh file under `folder` that imports, named by its path relative to the folder.

    A file that fails (unreadable, no closed volume, never stable) is logged and skipped.
    """
    folder = Path(folder)
    assets = []
    for path in mesh_files(folder):
        name = path.relative_to(folder).with_suffix("").as_posix().replace("/", "-")
        try:
            assets.append(import_mesh(path, config, cache, name))
        except (ValueError, IndexError) as error:
            log.warning("skipping %s: %s", path, error)
    return assets
