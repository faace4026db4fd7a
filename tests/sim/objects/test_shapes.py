"""Procedural shapes: deterministic, watertight, centred, within the size range, exact parts."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from hamnet.sim.objects import Mesh, ObjectLibraryConfig, ObjectSet, ShapeConfig
from hamnet.sim.objects.config import SHAPE_KINDS
from hamnet.sim.objects.mesh import center_of_mass, convex_hull, union
from hamnet.sim.objects.shapes import generate


def symmetric_difference(a: Mesh, b: Mesh) -> float:
    """Volume in exactly one of two closed meshes, relative to the first's volume."""
    both = trimesh.boolean.intersection([a.to_trimesh(), b.to_trimesh()], engine="manifold").volume
    either = union([a, b]).volume
    return (either - both) / a.volume


@pytest.mark.parametrize("kind", SHAPE_KINDS)
def test_same_seed_gives_the_same_shape_and_another_seed_does_not(kind: str) -> None:
    config = ShapeConfig()
    first = generate(kind, np.random.default_rng(3), config)
    again = generate(kind, np.random.default_rng(3), config)
    other = generate(kind, np.random.default_rng(4), config)
    assert np.array_equal(first.mesh.vertices, again.mesh.vertices)
    assert np.array_equal(first.mesh.faces, again.mesh.faces)
    assert first.mesh.digest() != other.mesh.digest()


@pytest.mark.parametrize("kind", SHAPE_KINDS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_shape_is_watertight_centred_and_sized(kind: str, seed: int) -> None:
    config = ShapeConfig()
    shape = generate(kind, np.random.default_rng(seed), config)
    solid = shape.mesh.to_trimesh()
    assert solid.is_watertight and solid.is_winding_consistent
    assert solid.volume > 0  # outward faces
    np.testing.assert_allclose(center_of_mass(shape.mesh), 0.0, atol=1e-9)
    low, high = config.extent
    extents = np.ptp(shape.mesh.vertices, axis=0)  # (3,)
    assert np.all(extents >= low - 1e-9) and np.all(extents <= high + 1e-9), extents
    assert shape.mesh.vertices.dtype == np.float64 and shape.mesh.faces.dtype == np.int32


@pytest.mark.parametrize("kind", SHAPE_KINDS)
def test_parts_are_convex_and_fill_the_shape(kind: str) -> None:
    shape = generate(kind, np.random.default_rng(0), ShapeConfig())
    for part in shape.parts:
        assert part.to_trimesh().is_watertight
        assert convex_hull(part.vertices).volume == pytest.approx(part.volume, rel=1e-6)
    assert symmetric_difference(shape.mesh, union(list(shape.parts))) < 1e-6


def test_compounds_are_not_convex() -> None:
    """The handle and the L's corner must survive: a hull would make them one convex blob."""
    for kind in ("l_shape", "t_shape", "mug"):
        shape = generate(kind, np.random.default_rng(0), ShapeConfig())
        assert len(shape.parts) > 1
        assert convex_hull(shape.mesh.vertices).volume > 1.05 * shape.mesh.volume


def test_procedural_set_is_deterministic_without_cache() -> None:
    """Everything, stable poses included, follows from the seed (computed twice, no cache)."""
    config = ObjectLibraryConfig(shapes=ShapeConfig(kinds=("box", "mug")), use_cache=False)
    first = ObjectSet.procedural(2, seed=7, config=config)
    again = ObjectSet.procedural(2, seed=7, config=config)
    assert first.names == again.names == ("box-s7-0000", "mug-s7-0001")
    for a, b in zip(first, again):
        assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
        assert np.array_equal(a.stable.orientations, b.stable.orientations)
        assert np.array_equal(a.stable.probabilities, b.stable.probabilities)


def test_procedural_set_cycles_kinds_and_extends(
    one_of_each: ObjectSet, library_config: ObjectLibraryConfig
) -> None:
    assert [a.source for a in one_of_each] == [f"procedural:{k}" for k in SHAPE_KINDS]
    smaller = ObjectSet.procedural(3, seed=0, config=library_config)
    assert smaller.names == one_of_each.names[:3]
    for a, b in zip(smaller, one_of_each):
        assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
