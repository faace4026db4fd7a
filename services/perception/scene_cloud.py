"""The environment (scene) cloud in simulation, batched in torch (B environments, any
device): points sampled uniformly from the visible surface of a scene's cuboids, cropped to
the workspace over the table (paper appendix "Point cloud sampling process"). The operations
on the sampled clouds (posing, FPS, kNN, the local cloud, corruption) live in `cloud_ops`.

Environment cloud without a boolean mesh union: every face of every cuboid is split into a
grid of triangles, triangles inside another cuboid are culled (all three vertices covered by
one convex box), points are drawn in proportion to the area of the triangles left, and the
few that land on a partly covered triangle's covered part are rejected and redrawn. The
result is uniform over the visible surface: exactly what sampling the union's surface gives.

"Covered" is exact for the coplanar contacts procedural scenes are full of: a point on a face
of cuboid A is covered by cuboid B when it lies inside B or on its boundary (within
`tolerance`), except on a face of B with the same outward normal, where the two faces are one
surface and the cuboid with the lower index keeps it. So a plate's underside and the table
top beneath it both vanish, while two plates whose tops meet in one plane show that plane
once.

Crop (the authors' `scene_cloud.crop_style: chamfer`, whose scene cloud is sampled inside a
workspace box: ham/src/ham/env/episode/scene_cloud.py:43-56): only the surface inside the
table's footprint, from `below` under the table top up to `height` above it, counts. Faces
are clipped to that box before they are split (exact for faces that are parallel or
perpendicular to its sides: table, plates, walls, ceiling), and points a tilted face (a ramp)
puts outside it are rejected like hidden ones. So the table's sides below the top, its
underside and the walls' outer faces are never sampled.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hamnet.perception.cloud_ops import env_chunks, gather, quaternion_matrix
from hamnet.task.cuboids import TABLE

MAX_ROUNDS = 32
"""Rejection rounds before the sampler gives up (one is the norm, see `sample_surface`)."""


@dataclass(frozen=True)
class Cuboids:
    """C cuboid slots of B scenes (the Scene message), as tensors on one device."""

    centre: torch.Tensor
    """(B, C, 3) m."""
    rotation: torch.Tensor
    """(B, C, 3, 3) cuboid-to-world rotation; columns are the cuboid's axes."""
    half_extent: torch.Tensor
    """(B, C, 3) m."""
    active: torch.Tensor
    """(B, C) bool."""

    @classmethod
    def from_quat(cls, centre, quat, half_extent, active) -> Cuboids:
        """From centres (B, C, 3), wxyz quaternions (B, C, 4), half extents and active mask."""
        return cls(centre, quaternion_matrix(quat), half_extent, active.bool())

    def rows(self, envs: slice) -> Cuboids:
        """The scenes `envs` of the batch."""
        return Cuboids(
            self.centre[envs], self.rotation[envs], self.half_extent[envs], self.active[envs]
        )


@dataclass(frozen=True)
class Triangles:
    """The faces of every cuboid split into T = C * 6 * grid^2 * 2 triangles."""

    vertices: torch.Tensor
    """(B, T, 3, 3) corners, world frame, m."""
    owner: torch.Tensor
    """(T,) cuboid slot each triangle belongs to."""
    normal: torch.Tensor
    """(B, T, 3) outward unit normal, world frame."""
    area: torch.Tensor
    """(B, T) m^2; 0 for triangles of inactive cuboids and culled ones."""


def covered(
    points: torch.Tensor,
    owner: torch.Tensor,
    normal: torch.Tensor,
    cuboids: Cuboids,
    tolerance: float,
) -> torch.Tensor:
    """Which surface points another active cuboid hides (see the module docstring).

    Args:
        points: (B, M, 3) points on cuboid faces, world frame, m.
        owner: (M,) or (B, M) slot of the cuboid each point lies on.
        normal: (B, M, 3) outward normal of the face each point lies on.
        cuboids: the scenes, C slots.
        tolerance: distance to a boundary that counts as on it, m.
    Returns:
        (B, M, C) bool: point m is covered by cuboid c.
    """
    offset = points[:, :, None, :] - cuboids.centre[:, None]  # (B, M, C, 3)
    local = torch.einsum("bmci,bcij->bmcj", offset, cuboids.rotation)  # (B, M, C, 3)
    local_normal = torch.einsum("bmi,bcij->bmcj", normal, cuboids.rotation)  # (B, M, C, 3)
    half = cuboids.half_extent[:, None]  # (B, 1, C, 3)
    inside = (local.abs() <= half + tolerance).all(-1)  # (B, M, C), boundary included
    on_face = (local.abs() - half).abs() <= tolerance  # (B, M, C, 3)
    same_normal = on_face & (torch.sign(local) * local_normal > 1.0 - 1e-4)
    slots = torch.arange(cuboids.active.shape[1], device=points.device)
    owner = owner.expand(points.shape[:2])  # (B, M)
    higher = slots[None, None, :] > owner[..., None]  # (B, M, C)
    kept_by_owner = same_normal.any(-1) & higher  # coplanar, same side: the lower index keeps it
    other = slots[None, None, :] != owner[..., None]
    return inside & ~kept_by_owner & other & cuboids.active[:, None, :]


def _face_grid(grid: int, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
    """Vertices of one face's grid in face coordinates and its triangles.

    Returns:
        (V, 2) vertex coordinates in [-1, 1]^2 (V = (grid+1)^2) and (grid^2 * 2, 3) vertex
        indices of the triangles.
    """
    steps = torch.linspace(-1.0, 1.0, grid + 1, device=device)
    uv = torch.stack(torch.meshgrid(steps, steps, indexing="ij"), dim=-1).reshape(-1, 2)  # (V, 2)
    i, j = torch.meshgrid(
        torch.arange(grid, device=device), torch.arange(grid, device=device), indexing="ij"
    )
    v00 = (i * (grid + 1) + j).reshape(-1)
    v10, v01, v11 = v00 + grid + 1, v00 + 1, v00 + grid + 2
    triangles = torch.cat([torch.stack([v00, v10, v11], -1), torch.stack([v00, v11, v01], -1)])
    return uv, triangles


def workspace_box(cuboids: Cuboids, below: float, height: float) -> Cuboids:
    """The crop box of each scene: the table's footprint, from `below` under the table top to
    `height` above it (authors' scene_cloud.py:51-55: 0.01 and the tallest case).

    Args:
        cuboids: B scenes; slot TABLE is the table.
        below: depth of the box under the table top, m.
        height: height of the box above the table top, m.
    Returns:
        One box (slot) per scene, in the table's frame.
    """
    rotation = cuboids.rotation[:, TABLE : TABLE + 1]  # (B, 1, 3, 3)
    half = cuboids.half_extent[:, TABLE : TABLE + 1].clone()  # (B, 1, 3)
    lift = half[..., 2] + (height - below) / 2  # (B, 1) box centre above the table's, m
    centre = cuboids.centre[:, TABLE : TABLE + 1] + rotation[..., 2] * lift[..., None]
    half[..., 2] = (height + below) / 2
    return Cuboids(centre, rotation, half, torch.ones_like(cuboids.active[:, :1]))


def inside(points: torch.Tensor, box: Cuboids, tolerance: float) -> torch.Tensor:
    """(B, M) whether points (B, M, 3) lie in the one-slot box of their scene (boundary in)."""
    local = torch.einsum("bmi,bij->bmj", points - box.centre[:, :1], box.rotation[:, 0])
    return (local.abs() <= box.half_extent[:, :1] + tolerance).all(-1)


def _clipped_faces(
    world: torch.Tensor, axis_u: torch.Tensor, axis_v: torch.Tensor, box: Cuboids, tolerance: float
) -> torch.Tensor:
    """Face coordinate ranges (B, C, 6, 2, 2) that keep each face inside the box.

    A face is `world + u * axis_u + v * axis_v` for u, v in [-1, 1]. A side of the box that
    only u (or only v) crosses bounds u (or v); a side parallel to the face keeps or drops
    the whole face; a side both cross (a tilted face) is left to rejection.

    Args:
        world: (B, C, 6, 3) face centres; axis_u, axis_v: (B, C, 6, 3) half-edge vectors, m.
    Returns:
        [..., 0, :] the u range, [..., 1, :] the v range; low > high where nothing is left.
    """
    offset = world - box.centre[:, :, None]  # (B, C, 6, 3), the box is one slot
    rot = box.rotation[:, 0]  # (B, 3, 3)
    p0 = torch.einsum("bcfi,bij->bcfj", offset, rot)  # (B, C, 6, 3) box frame
    a = torch.einsum("bcfi,bij->bcfj", axis_u, rot)
    b = torch.einsum("bcfi,bij->bcfj", axis_v, rot)
    half = box.half_extent[:, :, None] + tolerance  # (B, 1, 1, 3)
    eps = 1e-6 * (a.norm(dim=-1, keepdim=True) + b.norm(dim=-1, keepdim=True))
    only_a, only_b = (a.abs() > eps) & (b.abs() <= eps), (b.abs() > eps) & (a.abs() <= eps)
    neither = (a.abs() <= eps) & (b.abs() <= eps)
    ranges = []
    for step, only in ((a, only_a), (b, only_b)):
        safe = torch.where(only, step, torch.ones_like(step))
        ends = torch.stack([(-half - p0) / safe, (half - p0) / safe], -1)  # (B, C, 6, 3, 2)
        low = torch.where(only, ends.amin(-1), torch.full_like(p0, -1.0)).amax(-1).clamp(min=-1.0)
        high = torch.where(only, ends.amax(-1), torch.full_like(p0, 1.0)).amin(-1).clamp(max=1.0)
        ranges.append(torch.stack([low, high], -1))  # (B, C, 6, 2)
    out = (neither & (p0.abs() > half)).any(-1)  # (B, C, 6): a parallel side cuts it off
    ranges = torch.stack(ranges, -2)  # (B, C, 6, 2, 2)
    ranges[..., 0][out] = 1.0
    ranges[..., 1][out] = -1.0
    return ranges


FACE_AXES = torch.tensor([[0, 1, 2], [0, 1, 2], [1, 2, 0], [1, 2, 0], [2, 0, 1], [2, 0, 1]])
"""Per face: normal axis, then the two in-face axes (right-handed order)."""
FACE_SIGNS = torch.tensor([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
"""Per face: side of the normal axis (+x, -x, +y, -y, +z, -z)."""


def visible_triangles(
    cuboids: Cuboids, grid: int, tolerance: float, crop: Cuboids | None = None
) -> Triangles:
    """Split every face (clipped to `crop`, see the module docstring) into triangles and cull
    those another cuboid hides entirely.

    A triangle is culled when one cuboid covers all three of its vertices: a box is convex,
    so it then covers the whole triangle. Partly covered triangles stay (rejection handles
    them), so culling never removes visible surface.
    """
    device, dtype = cuboids.centre.device, cuboids.centre.dtype
    b, c = cuboids.active.shape
    uv, tri = _face_grid(grid, device)  # (V, 2), (G2, 3)
    uv = uv.to(dtype)
    axes, signs = FACE_AXES.to(device), FACE_SIGNS.to(device, dtype)
    half = cuboids.half_extent  # (B, C, 3)
    # Per face: its centre and the half-edge vectors along its two in-face axes, world frame.
    columns = lambda k: cuboids.rotation[:, :, :, axes[:, k]].permute(0, 1, 3, 2)
    extent = lambda k: half.gather(-1, axes[None, None, :, k].expand(b, c, 6))[..., None]
    normal = columns(0) * signs[:, None]  # (B, C, 6, 3)
    centre = cuboids.centre[:, :, None] + normal * extent(0)  # (B, C, 6, 3)
    axis_u, axis_v = columns(1) * extent(1), columns(2) * extent(2)  # (B, C, 6, 3), m
    if crop is None:
        ranges = torch.tensor([-1.0, 1.0], device=device, dtype=dtype).expand(b, c, 6, 2, 2)
    else:
        ranges = _clipped_faces(centre, axis_u, axis_v, crop, tolerance)  # (B, C, 6, 2, 2)
    low, span = ranges[..., 0], (ranges[..., 1] - ranges[..., 0]).clamp(min=0.0)  # (B, C, 6, 2)
    coords = low[:, :, :, None] + span[:, :, :, None] * (uv + 1.0) / 2  # (B, C, 6, V, 2)
    world = (
        centre[:, :, :, None]
        + coords[..., :1] * axis_u[:, :, :, None]
        + coords[..., 1:] * axis_v[:, :, :, None]
    )  # (B, C, 6, V, 3)
    v = len(uv)
    owner = torch.arange(c, device=device).repeat_interleave(6 * v)  # (C*6*V,)
    vertex_normal = normal[:, :, :, None, :].expand(b, c, 6, v, 3).reshape(b, -1, 3)
    hidden = covered(world.reshape(b, -1, 3), owner, vertex_normal, cuboids, tolerance)
    hidden = hidden.reshape(b, c, 6, v, c)  # (B, C, 6, V, C)
    culled = hidden[:, :, :, tri, :].all(-2).any(-1)  # (B, C, 6, G2)
    vertices = world[:, :, :, tri, :]  # (B, C, 6, G2, 3, 3)
    # (2|u| span_u / 2) x (2|v| span_v / 2): the face's kept part, (B, C, 6), m^2
    face_area = axis_u.norm(dim=-1) * axis_v.norm(dim=-1) * span.prod(-1)
    area = (face_area / (2 * grid * grid))[..., None].expand(-1, -1, -1, len(tri))  # (B, C, 6, G2)
    area = area * ~culled * cuboids.active[:, :, None, None]
    t = c * 6 * len(tri)
    return Triangles(
        vertices=vertices.reshape(b, t, 3, 3),
        owner=torch.arange(c, device=device).repeat_interleave(6 * len(tri)),
        normal=normal[:, :, :, None, :].expand(b, c, 6, len(tri), 3).reshape(b, t, 3),
        area=area.reshape(b, t),
    )


def _points_on(triangles: Triangles, index: torch.Tensor, generator) -> torch.Tensor:
    """Uniform points (B, M, 3) on the triangles `index` (B, M)."""
    b, m = index.shape
    corners = triangles.vertices.gather(
        1, index[..., None, None].expand(b, m, 3, 3)
    )  # (B, M, 3, 3)
    r = torch.rand(b, m, 2, device=index.device, dtype=corners.dtype, generator=generator)
    s = r[..., :1].sqrt()  # the square root makes the density uniform over the triangle
    weights = torch.cat([1 - s, s * (1 - r[..., 1:]), s * r[..., 1:]], -1)  # (B, M, 3)
    return torch.einsum("bmk,bmki->bmi", weights, corners)


def sample_surface(
    cuboids: Cuboids,
    num_points: int,
    grid: int = 2,
    tolerance: float = 1e-5,
    generator: torch.Generator | None = None,
    crop: Cuboids | None = None,
) -> torch.Tensor:
    """Points drawn uniformly from the visible surface of each scene's cuboids.

    Args:
        cuboids: B scenes of C slots; every scene needs an active cuboid.
        num_points: N points per scene.
        grid: face subdivision (see `CloudConfig.grid`).
        tolerance: boundary tolerance, m.
        generator: torch random generator on the cuboids' device (None: the global one).
        crop: one box per scene (`workspace_box`) the surface is cut to; None: all of it.
    Returns:
        (B, N, 3) world-frame points, m, in random order (any prefix is a uniform sample).
    """
    if not bool(cuboids.active.any(-1).all()):
        raise ValueError("every scene needs at least one active cuboid")
    return torch.cat(
        [
            _sample_visible(
                cuboids.rows(envs),
                num_points,
                grid,
                tolerance,
                generator,
                None if crop is None else crop.rows(envs),
            )
            for envs in env_chunks(len(cuboids.active))
        ]
    )


def _sample_visible(
    cuboids: Cuboids,
    num_points: int,
    grid: int,
    tolerance: float,
    generator: torch.Generator | None,
    crop: Cuboids | None,
) -> torch.Tensor:
    """`sample_surface` for a few environments at once (its point-in-box tests build
    (B, M, C, 3) tensors that stay in the CPU caches only for a few environments)."""
    triangles = visible_triangles(cuboids, grid, tolerance, crop)
    b = cuboids.active.shape[0]
    draws = num_points + num_points // 4  # most points survive: culling removed the hidden parts
    points, valid = [], []
    for _ in range(MAX_ROUNDS):
        index = torch.multinomial(
            triangles.area, draws, replacement=True, generator=generator
        )  # (B, M)
        candidate = _points_on(triangles, index, generator)  # (B, M, 3)
        normal = triangles.normal.gather(1, index[..., None].expand(b, draws, 3))
        hidden = covered(candidate, triangles.owner[index], normal, cuboids, tolerance).any(-1)
        if crop is not None:
            hidden |= ~inside(candidate, crop, tolerance)  # a tilted face's part outside
        points.append(candidate)
        valid.append(~hidden)
        if int(torch.cat(valid, 1).sum(1).min()) >= num_points:
            break
    else:
        raise RuntimeError(f"fewer than {num_points} visible points after {MAX_ROUNDS} rounds")
    points, valid = torch.cat(points, 1), torch.cat(valid, 1)  # (B, R*M, 3), (B, R*M)
    order = torch.argsort((~valid).to(torch.uint8), dim=1, stable=True)[:, :num_points]  # (B, N)
    return gather(points, order)
