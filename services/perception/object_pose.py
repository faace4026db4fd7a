"""The object's pose from its cloud, for a robot with cameras and no pose tracker: the
cloud's centroid, and a yaw about the world's vertical from the cloud's principal axis on
the table.

A stand-in for the paper's pose tracker (FoundationPose): the centroid of the visible
surface lies off the object's centre towards the cameras, a square footprint has no
principal axis (its yaw is then arbitrary), an axis is ambiguous by half a turn (the yaw is
kept in (-pi/2, pi/2]), and tilts are not seen. It gives the policy an object frame that
moves with the object, which is what its goal-relative inputs need first.
"""

from __future__ import annotations

import numpy as np

from hamnet.sim.quaternion import from_axis_angle

UP = np.array([0.0, 0.0, 1.0])


def estimate_pose(points: np.ndarray) -> np.ndarray:
    """(7,) position (m) and quaternion wxyz of an object cloud (N, 3), world frame."""
    centre = points.mean(axis=0)
    xy = points[:, :2] - centre[:2]
    _, vectors = np.linalg.eigh(xy.T @ xy)  # ascending eigenvalues: the last is the long axis
    axis = vectors[:, -1]
    yaw = np.arctan2(axis[1], axis[0])
    if yaw <= -np.pi / 2 or yaw > np.pi / 2:
        yaw -= np.copysign(np.pi, yaw)
    return np.concatenate([centre, from_axis_angle(UP, yaw)])
