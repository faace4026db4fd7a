"""Surface sampling for the object cloud: on the surface, area-weighted, seeded."""

from __future__ import annotations

import numpy as np

from hamnet.sim.objects import Mesh, ObjectSet, sample_surface
from hamnet.sim.objects.mesh import box_mesh


def on_surface(points: np.ndarray, mesh: Mesh, tolerance: float = 1e-9) -> np.ndarray:
    """(N,) whether each point lies inside some face (in its plane, barycentric coords >= 0)."""
    a, b, c = (mesh.vertices[mesh.faces[:, i]] for i in range(3))  # (F, 3) each
    normal = np.cross(b - a, c - a)  # (F, 3)
    offset = points[:, None, :] - a[None]  # (N, F, 3)
    in_plane = (
        np.abs(np.einsum("nfi,fi->nf", offset, normal)) / np.linalg.norm(normal, axis=1) < tolerance
    )
    # Barycentric coordinates from the two edge vectors.
    e0, e1 = b - a, c - a  # (F, 3)
    d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)  # (F,)
    d20, d21 = np.einsum("nfi,fi->nf", offset, e0), np.einsum("nfi,fi->nf", offset, e1)  # (N, F)
    det = d00 * d11 - d01**2
    v = (d11 * d20 - d01 * d21) / det
    w = (d00 * d21 - d01 * d20) / det
    inside = (v >= -1e-9) & (w >= -1e-9) & (v + w <= 1 + 1e-9)
    return np.any(in_plane & inside, axis=1)


def test_samples_lie_on_every_object_surface(one_of_each: ObjectSet) -> None:
    rng = np.random.default_rng(0)
    for asset in one_of_each:
        points = asset.sample_surface(512, rng)
        assert points.shape == (512, 3) and points.dtype == np.float64
        assert on_surface(points, asset.mesh).all(), asset.name


def test_points_off_the_surface_are_detected() -> None:
    """The checker itself can fail: a point inside the box is not on its surface."""
    box = box_mesh(np.full(3, -0.05), np.full(3, 0.05))
    assert on_surface(np.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.049]]), box).tolist() == [
        True,
        False,
    ]


def test_faces_are_hit_in_proportion_to_their_area() -> None:
    half = np.array([0.01, 0.04, 0.10])  # a box whose face pairs differ in area
    box = box_mesh(-half, half)
    points = sample_surface(box, 40_000, np.random.default_rng(1))
    axis = np.argmax(np.abs(points) / half, axis=1)  # (N,) which face pair each point is on
    share = np.bincount(axis, minlength=3) / len(points)
    area = np.array([half[1] * half[2], half[0] * half[2], half[0] * half[1]])  # per face pair
    np.testing.assert_allclose(share, area / area.sum(), atol=0.01)


def test_same_seed_gives_the_same_cloud(one_of_each: ObjectSet) -> None:
    asset = one_of_each[0]
    first = asset.sample_surface(512, np.random.default_rng(3))
    assert np.array_equal(first, asset.sample_surface(512, np.random.default_rng(3)))
    assert not np.array_equal(first, asset.sample_surface(512, np.random.default_rng(4)))
