"""Near arm starts: targets that leave the paddle room among the cuboids, and IK seeds."""

from __future__ import annotations

import numpy as np

from hamnet.fr3 import limits as fr3_limits
from hamnet.sim.robot_init import (
    Cuboids,
    RobotInitConfig,
    ik_seeds,
    inside_cuboids,
    joint_bounds,
    near_targets,
)

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def one_wall(yaw: float = 0.0, active: bool = True) -> Cuboids:
    """One environment with one wall: 2 cm thick (x), 1 m wide (y), 1 m high, centred at
    x = 0.6, turned by `yaw` about z."""
    quat = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    return Cuboids(np.array([[[0.6, 0.0, 0.5]]]), quat[None, None], np.array([[[0.01, 0.5, 0.5]]]),
                   np.array([[active]]))  # fmt: skip


def test_points_within_the_margin_of_a_cuboid_are_inside_along_its_own_axes() -> None:
    margin = np.array([0.07, 0.07, 0.01])
    points = np.array([[[0.6, 0.0, 0.5], [0.53, 0.0, 0.5], [0.515, 0.0, 0.5], [0.6, 0.56, 0.5],
                        [0.6, 0.58, 0.5], [0.6, 0.0, 1.005], [0.6, 0.0, 1.02]]])  # fmt: skip
    expected = [[True, True, False, True, False, True, False]]
    assert inside_cuboids(points, one_wall(), margin).tolist() == expected
    # Turned by 90 degrees the wall runs along x: 0.1 m off its centre in x is inside.
    turned = inside_cuboids(np.array([[[0.7, 0.0, 0.5], [0.6, 0.1, 0.5]]]), one_wall(np.pi / 2), margin)
    assert turned.tolist() == [[True, False]]
    assert not inside_cuboids(points, one_wall(active=False), margin).any()


def test_near_targets_avoid_a_wall_beside_the_object() -> None:
    """The object stands 5 cm in front of a wall: about 60% of the directions put the paddle
    in it. With 8 directions per draw a target is blocked only when all 8 are (~2%)."""
    rng = np.random.default_rng(0)
    config = RobotInitConfig()
    object_pos = np.tile([0.55, 0.0, 0.05], (200, 1))  # (K, 3)
    wall = one_wall()
    cuboids = Cuboids(*(np.repeat(field, 200, axis=0) for field in vars(wall).values()))
    targets = near_targets(rng, object_pos, np.full(200, 0.03), cuboids, config)  # (K, 3)
    blocked = inside_cuboids(targets[:, None, :], cuboids, np.asarray(config.near_clearance))
    assert blocked.mean() < 0.06
    one_direction = RobotInitConfig(near_directions=1)
    single = near_targets(rng, object_pos, np.full(200, 0.03), cuboids, one_direction)
    assert inside_cuboids(single[:, None, :], cuboids, np.asarray(config.near_clearance)).mean() > 0.4


def test_ik_seeds_start_at_home_then_spread_within_the_joint_ranges() -> None:
    rng = np.random.default_rng(1)
    np.testing.assert_array_equal(ik_seeds(rng, 3, 0.0, 0.9), np.tile(fr3_limits.Q_HOME, (3, 1)))
    seeds = ik_seeds(rng, 500, 0.6, 0.9)  # (500, J)
    low, high = joint_bounds(0.9)
    assert ((seeds >= low) & (seeds <= high)).all()
    assert 0.3 < np.std(seeds[:, 0]) < 0.8  # joint 1 is far from its limits: spread kept
