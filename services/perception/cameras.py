"""Depth cameras to clouds with open3d (the real-robot path): several depth images with
intrinsics, extrinsics and a segmentation mask become one object cloud and one scene cloud.

Per view and label: back-project the masked depth image; then over all views: workspace
crop, voxel downsampling (overlapping views would otherwise weigh double), statistical
outlier removal, and resampling to a fixed number of points. Cameras follow the OpenCV
convention (x right, y down, z forward); depth is in metres, 0 where invalid. The views
(`hamnet.camera.views.DepthView`) come from the camera service.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d

from hamnet.camera.views import OBJECT, SCENE, DepthView
from hamnet.perception.config import CameraConfig


def fuse(views: list[DepthView], label: int | None, config: CameraConfig) -> np.ndarray:
    """The cloud (N, 3) of one label (None: every pixel) over all views: back-projected,
    cropped, voxel downsampled and cleaned of statistical outliers, world frame, m."""
    cloud = o3d.geometry.PointCloud()
    for view in views:
        h, w = view.depth.shape
        if label is None:
            depth = view.depth.astype(np.float32)
        elif view.labels is None:
            raise ValueError("a view without labels cannot be split by label (use a segmenter)")
        else:
            depth = np.where(view.labels == label, view.depth, 0.0).astype(np.float32)
        k = view.intrinsics
        intrinsic = o3d.camera.PinholeCameraIntrinsic(w, h, k[0, 0], k[1, 1], k[0, 2], k[1, 2])
        cloud += o3d.geometry.PointCloud.create_from_depth_image(
            o3d.geometry.Image(depth),
            intrinsic,
            np.linalg.inv(view.camera_to_world),
            depth_scale=1.0,
            depth_trunc=config.max_depth,
        )
    box = o3d.geometry.AxisAlignedBoundingBox(
        np.array(config.workspace_min), np.array(config.workspace_max)
    )
    cloud = cloud.crop(box).voxel_down_sample(config.voxel_size)
    if len(cloud.points) > config.outlier_neighbors:
        cloud, _ = cloud.remove_statistical_outlier(
            config.outlier_neighbors, config.outlier_std_ratio
        )
    return np.asarray(cloud.points)


def resample(points: np.ndarray, num_points: int, rng: np.random.Generator) -> np.ndarray:
    """num_points (P, 3) drawn from points (N, 3): without replacement when N >= P."""
    if len(points) == 0:
        raise ValueError("no points left to resample (is the segment visible to any camera?)")
    index = rng.choice(len(points), num_points, replace=len(points) < num_points)
    return points[index].astype(np.float32)


def camera_clouds(
    views: list[DepthView],
    config: CameraConfig | None = None,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Object and scene clouds (P, 3) each from depth views, world frame, m."""
    config = config if config is not None else CameraConfig()
    rng = rng if rng is not None else np.random.default_rng(0)
    return tuple(
        resample(fuse(views, label, config), config.num_points, rng) for label in (OBJECT, SCENE)
    )
