"""The object velocity the sim publishes is in the world frame, as proto/sim.proto says."""

from __future__ import annotations

import math

import numpy as np

from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv


def test_object_angular_velocity_is_in_the_world_frame() -> None:
    """MuJoCo's free joint keeps the angular velocity in the body frame. With the object
    turned 90 deg about x, a spin about its own z axis is a spin about world -y: the
    body-frame value (0, 0, 1) fails this assertion, the world-frame (0, -1, 0) passes."""
    env = VectorEnv(SimConfig(num_envs=2, num_objects=2, nthread=1))
    w, p = env.world, env.physics
    half = math.sqrt(0.5)
    p.qpos[:, w.object_qpos[3:]] = [half, half, 0.0, 0.0]  # 90 deg about x
    p.qvel[:, w.object_dof] = [0.1, 0.2, 0.3, 0.0, 0.0, 1.0]  # linear (world), angular (body)
    velocity = env.observe().object_velocity  # (B, 6)
    expected = np.array([0.1, 0.2, 0.3, 0.0, -1.0, 0.0], np.float32)
    np.testing.assert_allclose(velocity, np.tile(expected, (2, 1)), atol=1e-6)
