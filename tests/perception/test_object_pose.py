"""The camera path's object pose from its cloud: the centroid, and the yaw of the cloud's
long axis on the table, kept in (-pi/2, pi/2]."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.perception.object_pose import estimate_pose
from hamnet.sim.quaternion import angle_between, from_axis_angle

UP = np.array([0.0, 0.0, 1.0])


def box_surface(yaw: float, centre: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Points on the top of a 0.2 x 0.06 x 0.04 m box turned by `yaw` about the vertical."""
    local = rng.uniform([-0.1, -0.03, 0.02], [0.1, 0.03, 0.02], size=(500, 3))
    c, s = np.cos(yaw), np.sin(yaw)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return local @ rotation.T + centre


@pytest.mark.parametrize("yaw", [0.0, 0.4, -1.2, 1.5])
def test_the_pose_of_a_long_box_is_its_centroid_and_its_long_axis(yaw: float) -> None:
    centre = np.array([0.5, -0.1, 0.3])
    pose = estimate_pose(box_surface(yaw, centre, np.random.default_rng(0)))
    assert np.allclose(pose[:3], centre + [0.0, 0.0, 0.02], atol=5e-3)
    assert angle_between(pose[3:], from_axis_angle(UP, yaw)) < 0.05


def test_a_half_turn_gives_the_same_pose() -> None:
    rng = np.random.default_rng(1)
    a = estimate_pose(box_surface(0.3, np.zeros(3), rng))
    b = estimate_pose(box_surface(0.3 + np.pi, np.zeros(3), rng))
    assert angle_between(a[3:], b[3:]) < 0.05 and -np.pi / 2 < 2 * np.arctan2(a[6], a[3]) <= np.pi / 2
