"""Which fused points are the object and which the scene: the `Segmenter` interface of the
depth-camera path (`hamnet perception --clouds-from cameras --segmenter mask|plane`).

- `MaskSegmenter`: the frames' own labels (the sim's segmentation render; tests).
- `PlaneSegmenter`: for a real camera without labels: the table top is the dominant plane
  (RANSAC, open3d `segment_plane`), and the object is the largest DBSCAN cluster above it;
  everything else is scene. It knows nothing of the robot: the arm must be cut out before
  (the workspace crop, or a self-filter; docs/cameras.md), or a cluster of it may win.

Both return un-resampled clouds, world frame, m: `camera_core` resamples them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import open3d as o3d

from hamnet.camera.views import OBJECT, SCENE, DepthView
from hamnet.perception.cameras import fuse
from hamnet.perception.config import CameraConfig, PlaneConfig, SegmenterName


class Segmenter(Protocol):
    """Splits one frame time's views into object and scene points."""

    def split(self, views: list[DepthView]) -> tuple[np.ndarray, np.ndarray]:
        """(object (N, 3), scene (M, 3)) points, world frame, m; either may be empty."""
        ...


@dataclass(frozen=True)
class MaskSegmenter:
    """The frames' labels: OBJECT pixels are the object, SCENE pixels the scene."""

    cameras: CameraConfig

    def split(self, views: list[DepthView]) -> tuple[np.ndarray, np.ndarray]:
        return fuse(views, OBJECT, self.cameras), fuse(views, SCENE, self.cameras)


@dataclass(frozen=True)
class PlaneSegmenter:
    """The largest cluster above the dominant plane is the object; the rest is scene."""

    cameras: CameraConfig
    plane: PlaneConfig

    def split(self, views: list[DepthView]) -> tuple[np.ndarray, np.ndarray]:
        points = fuse(views, None, self.cameras)
        c = self.plane
        if len(points) < 3:
            return np.zeros((0, 3)), points
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        o3d.utility.random.seed(c.seed)
        (a, b, n, d), _ = cloud.segment_plane(c.distance, 3, c.iterations)
        normal = np.array([a, b, n])
        height = (points @ normal + d) / np.linalg.norm(normal)
        if normal[2] < 0:  # point the normal up, away from the floor under the table
            height = -height
        above = np.flatnonzero(height > c.min_height)
        if len(above) == 0:
            return np.zeros((0, 3)), points
        labels = np.asarray(
            cloud.select_by_index(above).cluster_dbscan(c.cluster_eps, c.cluster_min_points)
        )
        if labels.max(initial=-1) < 0:
            return np.zeros((0, 3)), points
        largest = np.bincount(labels[labels >= 0]).argmax()
        is_object = np.zeros(len(points), bool)
        is_object[above[labels == largest]] = True
        return points[is_object], points[~is_object]


def make_segmenter(name: SegmenterName, cameras: CameraConfig, plane: PlaneConfig) -> Segmenter:
    """The segmenter called `name`."""
    if name == "mask":
        return MaskSegmenter(cameras)
    if name == "plane":
        return PlaneSegmenter(cameras, plane)
    raise ValueError(f"unknown segmenter {name!r} (mask or plane)")
