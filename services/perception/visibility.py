"""What the four depth cameras see, in simulation: masks of the surface points visible from
at least one camera of the paper's rig (four D435s around the table, `hamnet.camera.views.d435_rig`,
placed as `hamnet.camera.render` places them), and the fixed-size clouds kept from them.
The student's clouds are these (docs/policy.md, "Student inputs"); the teacher's stay full.

- Scene (`scene_visible`), exact: a point on a cuboid's surface is visible from a camera
  when the segment between them crosses no active cuboid's interior (slab test). Its own
  cuboid counts, so a face turned away from every camera is dropped.
- Object (`object_visible`): the object is a cloud without a mesh. A point must face a
  camera (its normal, estimated once per episode by `outward_normals`, points towards it:
  exact back-face culling on convex parts) and pass that camera's point z-buffer (points
  projected to a pinhole image whose pixels span `pixel` point spacings at the object, each
  also covering its 8 neighbouring pixels so a sparse cloud leaves no gaps; a point is
  visible within `depth_tolerance` spacings of its pixel's nearest point): concave parts
  hide what lies behind them. open3d's hidden point removal (HPR) is the reference in the
  tests, not the rule: it costs about 215 ms per step for 64 objects of 512 points and 4
  cameras on one CPU thread and has no batched or GPU form, this rule 26 ms (and 4 ms
  per environment for the normals at an episode's start; docs/policy.md, "Student
  inputs").

Not modelled: occlusion by the robot, and of the object by the scene. Shapes: B
environments, N points, K cameras, C cuboid slots.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import torch
from torch import Tensor

from hamnet.camera.views import d435_rig
from hamnet.perception.cloud_ops import env_chunks, gather, knn
from hamnet.perception.scene_cloud import Cuboids

RIG_RADIUS = 1.0
"""Horizontal distance of the cameras from the table centre, m (`d435_rig`'s default)."""
RIG_HEIGHT = 0.7
"""Height of the cameras above the table centre, m (`d435_rig`'s default)."""


class CameraView(Protocol):
    """What a camera source tells perception: which surface points its cameras see. The
    analytic `RigVisibility` is one; a rendered-depth source answers the same questions by
    depth-testing the points against its images, and perception does not change."""

    def scene(self, points: Tensor, cuboids: Cuboids, cameras: Tensor) -> Tensor:
        """(B, N) bool: scene points (B, N, 3) seen by a camera (B, K, 3) of their scene."""

    def object(self, points: Tensor, normals: Tensor, cameras: Tensor) -> Tensor:
        """(B, N) bool: posed object points (B, N, 3) with outward normals (B, N, 3) seen
        by a camera (B, K, 3)."""


class RigVisibility:
    """Exact scene visibility and a z-buffer for the object (the module docstring)."""

    def __init__(self, pixel: float, depth_tolerance: float, tolerance: float) -> None:
        self.pixel, self.depth_tolerance, self.tolerance = pixel, depth_tolerance, tolerance

    def scene(self, points: Tensor, cuboids: Cuboids, cameras: Tensor) -> Tensor:
        """`scene_visible`."""
        return scene_visible(points, cuboids, cameras, self.tolerance)

    def object(self, points: Tensor, normals: Tensor, cameras: Tensor) -> Tensor:
        """`object_visible`."""
        return object_visible(points, normals, cameras, self.pixel, self.depth_tolerance)


def camera_positions(
    target: Tensor, radius: float = RIG_RADIUS, height: float = RIG_HEIGHT
) -> Tensor:
    """(B, 4, 3) world positions of the rig's cameras looking at targets (B, 3), m: MuJoCo's
    free camera at `d435_rig`'s azimuths sits at lookat - distance * forward, that is
    `radius` m back along each azimuth and `height` m up."""
    azimuth = torch.tensor(
        [np.radians(a) for _, a, _ in d435_rig(np.zeros(3), radius, height)],
        dtype=target.dtype,
        device=target.device,
    )  # (4,) rad
    offset = torch.stack(
        (
            -radius * torch.cos(azimuth),
            -radius * torch.sin(azimuth),
            torch.full_like(azimuth, height),
        ),
        dim=-1,
    )  # (4, 3)
    return target[:, None, :] + offset


def scene_visible(points: Tensor, cuboids: Cuboids, cameras: Tensor, tolerance: float) -> Tensor:
    """(B, N) bool: the surface points (B, N, 3) that some camera (B, K, 3) sees past every
    active cuboid (each shrunk by `tolerance` m, so the face a point lies on does not hide
    it). Works a few environments at a time: the (B, N, K, C) slab tests are large."""
    return torch.cat(
        [
            _unblocked(points[rows], cuboids.rows(rows), cameras[rows], tolerance).any(-1)
            for rows in env_chunks(len(points))
        ]
    )


def _unblocked(points: Tensor, cuboids: Cuboids, cameras: Tensor, tolerance: float) -> Tensor:
    """(B, N, K) bool: the segment from camera k to point n crosses no cuboid."""
    rotation = cuboids.rotation  # (B, C, 3, 3), columns are the cuboid's axes
    origin = torch.einsum(
        "bkci,bcij->bkcj", cameras[:, :, None] - cuboids.centre[:, None], rotation
    )
    ray = points[:, :, None] - cameras[:, None]  # (B, N, K, 3)
    direction = torch.einsum("bnki,bcij->bnkcj", ray, rotation)  # (B, N, K, C, 3)
    direction = torch.where(direction.abs() < 1e-12, torch.full_like(direction, 1e-12), direction)
    half = (cuboids.half_extent - tolerance)[:, None, None]  # (B, 1, 1, C, 3)
    near = (-half - origin[:, None]) / direction  # segment parameter of each slab's sides
    far = (half - origin[:, None]) / direction
    enter = torch.minimum(near, far).amax(-1)  # (B, N, K, C)
    leave = torch.maximum(near, far).amin(-1)
    crossed = (enter < leave) & (enter < 1.0) & (leave > 0.0)  # the segment is t in [0, 1]
    return ~(crossed & cuboids.active[:, None, None]).any(-1)


def point_spacing(points: Tensor) -> Tensor:
    """(B, 1, 1) typical distance between neighbouring points of clouds (B, N, 3), m: the
    side of each point's share of a sphere with the cloud's radius of gyration."""
    centre = points.mean(1, keepdim=True)  # (B, 1, 3)
    gyration = (points - centre).square().sum(-1).mean(1)  # (B,) m^2
    return (4 * torch.pi * gyration / points.shape[1]).sqrt()[:, None, None]


def outward_normals(points: Tensor, neighbours: int = 10) -> Tensor:
    """(B, N, 3) unit normals of clouds (B, N, 3): the least-variance direction of each
    point's `neighbours` nearest points, turned away from the centroid (right on convex
    parts; a concave pocket's may point inwards, and the z-buffer still hides what is
    behind the pocket's rim)."""
    near = gather(points, knn(points, points, neighbours))  # (B, N, k, 3)
    centred = near - near.mean(2, keepdim=True)
    normal = torch.linalg.eigh(centred.mT @ centred).eigenvectors[..., 0]  # (B, N, 3)
    outward = ((points - points.mean(1, keepdim=True)) * normal).sum(-1, keepdim=True) >= 0
    return torch.where(outward, normal, -normal)


def object_visible(
    points: Tensor, normals: Tensor, cameras: Tensor, pixel: float, depth_tolerance: float
) -> Tensor:
    """(B, N) bool: the object points (B, N, 3), outward normals (B, N, 3), that some
    camera (B, K, 3) sees: facing it and first in its z-buffer.

    Args:
        pixel: pixel size at the object's centroid, in point spacings (`point_spacing`):
            smaller leaves holes a hidden point shows through, larger hides points behind
            nearer ones of the same face.
        depth_tolerance: how far behind its pixel's nearest point a point still counts as
            seen, in point spacings (walls thinner than this show both faces).
    """
    b, n, _ = points.shape
    k = cameras.shape[1]
    spacing = point_spacing(points)  # (B, 1, 1) m
    centre = points.mean(1, keepdim=True)  # (B, 1, 3)
    forward = torch.nn.functional.normalize(centre - cameras, dim=-1)  # (B, K, 3)
    up = torch.zeros_like(forward)
    up[..., 2] = 1.0
    right = torch.nn.functional.normalize(torch.cross(forward, up, dim=-1), dim=-1)
    up = torch.cross(right, forward, dim=-1)
    ray = points[:, None] - cameras[:, :, None]  # (B, K, N, 3)
    depth = (ray * forward[:, :, None]).sum(-1)  # (B, K, N) along the optical axis, m
    focal = (centre - cameras).norm(dim=-1, keepdim=True) / (pixel * spacing)  # (B, K, 1)
    u = torch.floor((ray * right[:, :, None]).sum(-1) / depth * focal).long()  # (B, K, N)
    v = torch.floor((ray * up[:, :, None]).sum(-1) / depth * focal).long()
    half = int(max(u.abs().max(), v.abs().max())) + 2  # the image covers every splat
    side = 2 * half + 1
    distance = ray.norm(dim=-1)  # (B, K, N), m
    image = torch.arange(b * k, device=points.device).reshape(b, k, 1) * side * side
    nearest = torch.full(
        (b * k * side * side,), float("inf"), device=points.device, dtype=distance.dtype
    )
    for du in (-1, 0, 1):
        for dv in (-1, 0, 1):
            splat = image + (u + du + half) * side + (v + dv + half)  # (B, K, N)
            nearest.scatter_reduce_(0, splat.flatten(), distance.flatten(), "amin")
    own = (image + (u + half) * side + (v + half)).flatten()
    first = distance <= nearest[own].reshape(b, k, n) + depth_tolerance * spacing  # (B, K, N)
    facing = (normals[:, None] * ray).sum(-1) < 0  # the normal points back at the camera
    return (first & facing).any(1)


def keep(mask: Tensor, count: int, generator: torch.Generator | None) -> Tensor:
    """(B, count) indices of points that `mask` (B, N) keeps: the kept ones in their order
    (a prefix of a random-order cloud stays uniform), then, when fewer are kept, copies of
    kept ones drawn at random. A cloud with none kept keeps all (a fully hidden object still
    needs `count` points; its full cloud is the least wrong answer)."""
    n = mask.shape[1]
    if count > n:
        raise ValueError(f"cannot keep {count} of {n} points")
    mask = mask | ~mask.any(1, keepdim=True)  # (B, N)
    order = torch.argsort((~mask).to(torch.uint8), dim=1, stable=True)[:, :count]  # (B, count)
    copies = torch.multinomial(mask.float(), count, replacement=True, generator=generator)
    slot = torch.arange(count, device=mask.device)[None]  # (1, count)
    return torch.where(slot < mask.sum(1, keepdim=True), order, copies)
