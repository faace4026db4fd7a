"""The scene cloud's crop to the workspace over the table (authors' `crop_style: chamfer`):
only the table's footprint, from 1 cm under its top up to the workspace height. Without it,
about 40% of a sim scene's points lay on the table's sides and underside and on the walls'
outer faces, which no camera above the table sees."""

from __future__ import annotations

import numpy as np
import torch

from hamnet.perception.config import CloudConfig
from hamnet.perception.scene_cloud import Cuboids, sample_surface, workspace_box
from hamnet.sim.scene import sample_scenes

BELOW, HEIGHT = 0.01, 0.65
IDENTITY = [1.0, 0.0, 0.0, 0.0]


def scene(*specs) -> Cuboids:
    """One scene of boxes (centre, half extent, quaternion); slot 0 is the table."""
    centre = torch.tensor([[s[0] for s in specs]], dtype=torch.float64)
    half = torch.tensor([[s[1] for s in specs]], dtype=torch.float64)
    quat = torch.tensor([[s[2] if len(s) > 2 else IDENTITY for s in specs]], dtype=torch.float64)
    return Cuboids.from_quat(centre, quat, half, torch.ones(1, len(specs), dtype=torch.bool))


def outside_workspace(points: torch.Tensor, top: float, half_xy, centre_xy, margin=1e-5):
    """(N,) points under the top minus BELOW, above it plus HEIGHT or off the footprint."""
    local = points[:, :2] - torch.tensor(centre_xy, dtype=points.dtype)
    off = (local.abs() > torch.tensor(half_xy, dtype=points.dtype) + margin).any(-1)
    return off | (points[:, 2] < top - BELOW - margin) | (points[:, 2] > top + HEIGHT + margin)


def test_crop_keeps_the_top_and_the_walls_inner_face_uniformly() -> None:
    """A 1 m tall table standing on the floor (top at z = 0), a wall outside its +x edge
    reaching 0.3 m above the top and a ceiling above the workspace. Every point lies in the
    box; the top and the wall's inner face share the points in proportion to their areas
    (0.4 x 0.6 against 0.3 x 0.6: the part of the wall under the top is hidden by the table),
    with the table's three other sides in the 1 cm band (0.014 m^2), so clipping keeps the
    sampling uniform."""
    cuboids = scene(
        ([0.0, 0.0, -0.5], [0.2, 0.3, 0.5]),  # table, floor at -1
        ([0.21, 0.0, -0.35], [0.01, 0.3, 0.65]),  # wall: from the floor to 0.3 m
        ([0.0, 0.0, 1.0], [0.22, 0.32, 0.01]),  # ceiling above the workspace: cut off
    )
    crop = workspace_box(cuboids, BELOW, HEIGHT)
    generator = torch.Generator().manual_seed(0)
    points = sample_surface(cuboids, 20000, generator=generator, crop=crop)[0]
    assert not bool(outside_workspace(points, 0.0, (0.2, 0.3), (0.0, 0.0)).any())
    on_wall = (points[:, 0] - 0.2).abs() < 1e-6
    on_top = points[:, 2].abs() < 1e-6
    band = (points[:, 2] < 0.0) & ~on_wall  # the table's sides, 1 cm under the top
    assert float((on_wall | on_top | band).double().mean()) > 0.999  # + the wall top's sliver
    np.testing.assert_allclose(float(band.double().mean()), 0.014 / 0.434, rtol=0.15)
    np.testing.assert_allclose(float(on_wall.sum()) / float(on_top.sum()), 0.18 / 0.24, rtol=0.05)


def test_crop_rejects_the_part_of_a_tilted_face_outside_the_box() -> None:
    """A ramp tilted by 23 degrees over the table's front edge: its faces cross the box's
    sides obliquely, so clipping cannot cut them; rejection keeps every point inside."""
    tilt = [np.cos(0.2), 0.0, np.sin(0.2), 0.0]
    cuboids = scene(
        ([0.0, 0.0, -0.5], [0.2, 0.3, 0.5]),
        ([-0.2, 0.0, 0.0], [0.1, 0.3, 0.01], tilt),
    )
    crop = workspace_box(cuboids, BELOW, HEIGHT)
    generator = torch.Generator().manual_seed(3)
    points = sample_surface(cuboids, 5000, generator=generator, crop=crop)[0]
    assert not bool(outside_workspace(points, 0.0, (0.2, 0.3), (0.0, 0.0)).any())
    assert bool((points[:, 2] > 0.01).any()), "the ramp's upper part is kept"


def test_crop_drops_what_a_camera_above_the_table_cannot_see_in_sim_scenes() -> None:
    """32 scenes from the sim's sampler: uncropped, many points lie on the sides of the
    table and under it; cropped, none lies under the top minus 1 cm or off the footprint."""
    scenes = sample_scenes(np.random.default_rng(0), np.full(32, 0.08))
    tensor = lambda a: torch.from_numpy(np.asarray(a, dtype=np.float64))  # noqa: E731
    cuboids = Cuboids.from_quat(
        tensor(scenes.centre), tensor(scenes.quat), tensor(scenes.half_extent),
        torch.from_numpy(scenes.active),
    )  # fmt: skip
    config = CloudConfig()
    crop = workspace_box(cuboids, config.crop_below, config.workspace_height)
    generator = torch.Generator().manual_seed(1)
    cropped = sample_surface(cuboids, 512, generator=generator, crop=crop)  # (32, 512, 3)
    uncropped = sample_surface(cuboids, 512, generator=generator)
    centre, half = scenes.centre[:, 0], scenes.half_extent[:, 0]  # the table, (32, 3)
    shares = []
    for points in (cropped, uncropped):
        outside = [
            outside_workspace(points[i], scenes.table_top[i], half[i, :2], centre[i, :2])
            for i in range(32)
        ]
        shares.append(float(torch.stack(outside).double().mean()))
    assert shares[0] == 0.0
    assert shares[1] > 0.2
