"""Cloud sampling on hand-built boxes: coverage, culling, area-proportional counts; posing,
local cloud against brute force, FPS and kNN against simple references, corruption."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from hamnet.perception import cloud_ops
from hamnet.perception.cloud_ops import (
    corrupt,
    farthest_point_sample,
    knn,
    local_cloud,
    pose_points,
    quaternion_matrix,
)
from hamnet.perception.scene_cloud import Cuboids, sample_surface
from hamnet.sim import quaternion

IDENTITY = [1.0, 0.0, 0.0, 0.0]


def boxes(*specs, active=None) -> Cuboids:
    """One scene of boxes given as (centre, half extent, quaternion)."""
    centre = torch.tensor([[s[0] for s in specs]], dtype=torch.float64)
    half = torch.tensor([[s[1] for s in specs]], dtype=torch.float64)
    quat = torch.tensor([[s[2] if len(s) > 2 else IDENTITY for s in specs]], dtype=torch.float64)
    active = torch.ones(1, len(specs), dtype=torch.bool) if active is None else torch.tensor([active])
    return Cuboids.from_quat(centre, quat, half, active)


def inside_any(points: torch.Tensor, cuboids: Cuboids, margin: float) -> torch.Tensor:
    """(N,) whether each point (N, 3) lies deeper than `margin` inside an active cuboid."""
    local = torch.einsum("nci,cij->ncj", points[:, None] - cuboids.centre[0], cuboids.rotation[0])
    deep = (local.abs() < cuboids.half_extent[0] - margin).all(-1)  # (N, C)
    return (deep & cuboids.active[0]).any(-1)


def test_quaternion_matrix_matches_the_sims_numpy_convention() -> None:
    q = np.random.default_rng(0).normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    np.testing.assert_allclose(quaternion_matrix(torch.tensor(q)).numpy(), quaternion.to_matrix(q), atol=1e-12)


def test_single_box_counts_follow_face_areas() -> None:
    """A 0.4 x 0.2 x 0.1 box: the share of points on each face pair is its share of the area."""
    scene = boxes(([0.0, 0.0, 0.0], [0.2, 0.1, 0.05]))
    points = sample_surface(scene, 20000, generator=torch.Generator().manual_seed(0))[0]
    half = torch.tensor([0.2, 0.1, 0.05], dtype=torch.float64)
    on_face = (points.abs() - half).abs() < 1e-9  # (N, 3): which face pair each point is on
    assert bool(on_face.any(1).all())
    areas = torch.tensor([0.2 * 0.1, 0.4 * 0.1, 0.4 * 0.2])  # yz, xz, xy face areas (one side)
    expected = areas / areas.sum()
    observed = on_face.double().mean(0)
    np.testing.assert_allclose(observed, expected, atol=0.015)


def test_stacked_boxes_cull_the_covered_part_and_keep_the_rest_uniform() -> None:
    """A small box standing on a table: no point inside either box, none on the footprint
    of the small box on the table top, none on its underside; the table top's visible part
    and the small box's top get points in proportion to their areas."""
    table = ([0.0, 0.0, 0.0], [0.5, 0.5, 0.1])
    block = ([0.1, 0.0, 0.2], [0.1, 0.1, 0.1])
    scene = boxes(table, block)
    points = sample_surface(scene, 30000, generator=torch.Generator().manual_seed(1))[0]
    assert not bool(inside_any(points, scene, 1e-6).any())
    x, y, z = points.unbind(-1)
    top = (z - 0.1).abs() < 1e-9
    footprint = top & ((x - 0.1).abs() < 0.1 - 1e-6) & (y.abs() < 0.1 - 1e-6)
    assert int(footprint.sum()) == 0
    block_top = (z - 0.3).abs() < 1e-9
    table_area = 2 * (1.0 * 1.0) + 4 * (1.0 * 0.2) - 0.2 * 0.2  # both big faces, sides, minus footprint
    block_area = 5 * 0.2 * 0.2  # its underside is covered
    total = table_area + block_area
    np.testing.assert_allclose(float(top.double().mean()), (1.0 - 0.04) / total, atol=0.01)
    np.testing.assert_allclose(float(block_top.double().mean()), 0.04 / total, atol=0.005)


def test_coplanar_tops_show_once_and_inactive_boxes_vanish() -> None:
    """Two overlapping plates whose tops share a plane: the plane keeps points over the whole
    union (no hole where both claim it); an inactive box adds nothing and hides nothing."""
    a = ([0.0, 0.0, 0.0], [0.2, 0.2, 0.05])
    b = ([0.2, 0.0, 0.0], [0.2, 0.2, 0.05])
    ghost = ([0.0, 0.0, 0.0], [0.3, 0.3, 0.3])
    scene = boxes(a, b, ghost, active=[True, True, False])
    points = sample_surface(scene, 20000, generator=torch.Generator().manual_seed(2))[0]
    x, y, z = points.unbind(-1)
    top = (z - 0.05).abs() < 1e-9
    overlap = top & (x > 0.0 + 0.01) & (x < 0.2 - 0.01)
    total = 2 * (0.6 * 0.4) + 2 * (0.6 * 0.1) + 2 * (0.4 * 0.1)  # the union is a 0.6 x 0.4 x 0.1 box
    np.testing.assert_allclose(float(overlap.double().mean()), (0.18 * 0.4) / total, atol=0.01)
    assert float(z.abs().max()) <= 0.05 + 1e-9  # nothing from the 0.3 m ghost


def test_rotated_box_points_lie_on_its_surface() -> None:
    quat = quaternion.from_axis_angle(np.array([0.0, 0.6, 0.8]), np.array(0.7)).tolist()
    scene = boxes(([0.3, -0.2, 0.5], [0.1, 0.2, 0.3], quat))
    points = sample_surface(scene, 2000)[0]
    local = (points - scene.centre[0, 0]) @ scene.rotation[0, 0]
    gap = (local.abs() - scene.half_extent[0, 0]).abs().min(-1).values
    assert float(gap.max()) < 1e-9 and bool((local.abs() <= scene.half_extent[0, 0] + 1e-9).all())


def test_scene_without_active_cuboid_is_an_error() -> None:
    with pytest.raises(ValueError, match="active"):
        sample_surface(boxes(([0.0, 0.0, 0.0], [0.1, 0.1, 0.1]), active=[False]), 10)


def test_pose_points_rotates_then_translates() -> None:
    points = torch.tensor([[[1.0, 0.0, 0.0]]])
    half_turn_z = [0.0, 0.0, 0.0, 1.0]
    pose = torch.tensor([[0.5, 0.5, 0.5, *half_turn_z]])
    np.testing.assert_allclose(pose_points(points, pose).numpy(), [[[-0.5, 0.5, 0.5]]], atol=1e-6)


@pytest.mark.parametrize("chunk", [8, 2])
def test_local_cloud_matches_brute_force(chunk: int, monkeypatch) -> None:
    """Also with environments taken 2 at a time (3 environments: a full and a partial chunk)."""
    monkeypatch.setattr(cloud_ops, "ENV_CHUNK", chunk)
    g = torch.Generator().manual_seed(3)
    scene, keypoints = torch.rand(3, 300, 3, generator=g), torch.rand(3, 7, 3, generator=g)
    local = local_cloud(scene, keypoints, 40)
    for b in range(3):
        distance = [min(float(torch.linalg.norm(p - k)) for k in keypoints[b]) for p in scene[b]]
        expected = scene[b][np.argsort(distance)[:40]]
        np.testing.assert_allclose(local[b].numpy(), expected.numpy())


def fps_reference(points: np.ndarray, k: int) -> list[int]:
    """Textbook FPS on one cloud, starting from the point farthest from the centroid."""
    chosen = [int(np.argmax(((points - points.mean(0)) ** 2).sum(1)))]
    distance = np.full(len(points), np.inf)
    for _ in range(k - 1):
        distance = np.minimum(distance, ((points - points[chosen[-1]]) ** 2).sum(1))
        chosen.append(int(np.argmax(distance)))
    return chosen


def test_fps_and_knn_match_simple_references() -> None:
    points = torch.rand(3, 200, 3, generator=torch.Generator().manual_seed(4), dtype=torch.float64)
    chosen = farthest_point_sample(points, 16)
    for b in range(3):
        assert chosen[b].tolist() == fps_reference(points[b].numpy(), 16)
    centres = points[:, :5]
    neighbours = knn(points, centres, 8)  # (B, 5, 8)
    for b, c in itertools.product(range(3), range(5)):
        distance = np.linalg.norm(points[b].numpy() - centres[b, c].numpy(), axis=1)
        assert neighbours[b, c].tolist() == np.argsort(distance)[:8].tolist()


def test_corrupt_keeps_size_and_replaces_with_existing_points() -> None:
    g = torch.Generator().manual_seed(5)
    points = torch.rand(4, 512, 3, generator=g)
    dropped = corrupt(points, 0.0, 0.3, g)
    assert dropped.shape == points.shape
    changed = (dropped != points).any(-1)  # (B, P)
    assert 0.2 < float(changed.double().mean()) < 0.4
    for b in range(4):  # every replacement is a copy of a point of the same cloud
        copies = dropped[b][changed[b]]  # (M, 3)
        assert bool((copies[:, None] == points[b][None]).all(-1).any(-1).all())
    noisy = corrupt(points, 0.01, 0.0, g)
    assert 0.008 < float((noisy - points).std()) < 0.012
