"""The depth-camera path on depth images rendered by MuJoCo (EGL, in its own process) from
four D435-like cameras: fused clouds agree with the analytic clouds of the same scene."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import torch

from hamnet.camera.views import SCENE, DepthView
from hamnet.perception.cameras import camera_clouds, fuse
from hamnet.perception.cloud_ops import pose_points
from hamnet.perception.config import CameraConfig
from hamnet.perception.scene_cloud import Cuboids, sample_surface


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> dict[str, np.ndarray]:
    out = tmp_path_factory.mktemp("render") / "views.npz"
    env = {**os.environ, "MUJOCO_GL": "egl"}
    subprocess.run([sys.executable, "-m", "hamnet.camera.render", str(out)], check=True, env=env, timeout=120)
    return dict(np.load(out))


def views_of(z: dict[str, np.ndarray]) -> list[DepthView]:
    return [DepthView(z[f"depth_{i}"], z[f"labels_{i}"], z[f"intrinsics_{i}"], z[f"camera_to_world_{i}"])
            for i in range(4)]  # fmt: skip


def nearest(a: np.ndarray, b: torch.Tensor) -> torch.Tensor:
    """(N,) distance from each point of a (N, 3) to the cloud b (M, 3), m."""
    return torch.cdist(torch.as_tensor(a, dtype=torch.float64), b).min(1).values


def test_fused_depth_matches_the_analytic_scene_and_object(rendered) -> None:
    z = rendered
    t = lambda name: torch.as_tensor(z[name], dtype=torch.float64)[None]  # noqa: E731
    cuboids = Cuboids.from_quat(t("centre"), t("quat"), t("half_extent"), torch.as_tensor(z["active"])[None])
    surface = sample_surface(cuboids, 40000, generator=torch.Generator().manual_seed(0))[0]  # ~1 cm spacing
    obj_surface = pose_points(t("object_points"), t("object_pose"))[0]  # (512, 3)
    views = views_of(z)
    scene_full = fuse(views, SCENE, CameraConfig())
    assert len(scene_full) > 2000
    distance = nearest(scene_full[np.random.default_rng(0).choice(len(scene_full), 2000)], surface)
    assert float(distance.median()) < 0.008 and float(torch.quantile(distance, 0.95)) < 0.02
    obj, scene = camera_clouds(views)
    assert obj.shape == scene.shape == (512, 3) and obj.dtype == np.float32
    assert float(nearest(scene, surface).mean()) < 0.01
    seen = torch.as_tensor(obj, dtype=torch.float64)
    chamfer = 0.5 * (float(nearest(obj, obj_surface).mean()) + float(nearest(obj_surface.numpy(), seen).mean()))
    assert chamfer < 0.02  # the hidden underside of the object counts against it


def test_points_outside_the_workspace_or_label_are_dropped(rendered) -> None:
    views = views_of(rendered)
    floor = float(np.median(fuse(views, SCENE, CameraConfig())[:, 2]))  # the scene's heights vary
    crop = CameraConfig(workspace_min=(-1.0, -1.0, floor), workspace_max=(2.0, 1.0, 2.0))
    assert float(fuse(views, SCENE, crop)[:, 2].min()) >= floor
    blank = [DepthView(v.depth, np.zeros_like(v.labels), v.intrinsics, v.camera_to_world) for v in views]
    assert len(fuse(blank, SCENE, CameraConfig())) == 0
    with pytest.raises(ValueError, match="no points"):
        camera_clouds(blank)
