"""One depth camera's frame and where the rig's cameras stand: what the camera service's
sources produce and perception fuses into clouds.

Cameras follow the OpenCV convention (x right, y down, z forward); depth is in metres, 0
where invalid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SCENE, OBJECT = 1, 2
"""Segmentation labels (0: anything else, e.g. the robot or the floor)."""


@dataclass(frozen=True)
class DepthView:
    """One camera's frame."""

    depth: np.ndarray
    """(H, W) float32 depth along the optical axis, m; 0 where there is no reading."""
    labels: np.ndarray | None
    """(H, W) uint8 segmentation: SCENE, OBJECT or 0; None when the camera has none (a real
    camera: `hamnet.perception.segmenters` then splits the fused cloud)."""
    intrinsics: np.ndarray
    """(3, 3) pinhole matrix, pixels."""
    camera_to_world: np.ndarray
    """(4, 4) pose of the camera in the world (OpenCV axes)."""


def d435_rig(
    target: np.ndarray, radius: float = 1.0, height: float = 0.7
) -> list[tuple[np.ndarray, float, float]]:
    """Four cameras around the table as in the paper's setup: (look-at point (3,), azimuth
    deg, elevation deg) each, at `radius` m from `target` and `height` m above it, 90 degrees
    apart, starting 45 degrees off the robot's axis (the robot is at the origin facing +x)."""
    elevation = -np.degrees(np.arctan2(height, radius))
    return [(np.asarray(target, float), 45.0 + 90.0 * i, float(elevation)) for i in range(4)]
