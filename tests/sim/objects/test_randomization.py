"""Per-episode physics randomization: ranges, batching, determinism, validation."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.objects import ObjectRandomization, sample_physics
from hamnet.sim.objects.randomization import max_rule_frictions
from hamnet.task.physics import PHYSICS_PARAM_NAMES


def test_samples_lie_in_the_configured_ranges() -> None:
    config = ObjectRandomization()
    object_radius = np.array([0.05, 0.08, 0.12, 0.2] * 256)  # (B,) library sizes, m
    physics = sample_physics(config, np.random.default_rng(0), object_radius)
    for values in (physics.scale, physics.mass, physics.friction, physics.restitution):
        assert values.shape == object_radius.shape
    radius = physics.scale * object_radius  # what the object is scaled to
    assert radius.min() >= 0.05 and radius.max() <= 0.10
    assert physics.mass.min() >= 0.1 and physics.mass.max() <= 0.5
    assert physics.friction.min() >= 0.2 and physics.friction.max() <= 1.0
    assert physics.restitution.min() >= 0.0 and physics.restitution.max() <= 0.2
    # Uniform, so a big batch covers most of each range.
    assert np.ptp(radius) > 0.045 and np.ptp(physics.mass) > 0.35


def test_scale_range_is_used_without_a_radius_range() -> None:
    config = ObjectRandomization(radius=None, scale=(0.8, 1.2))
    physics = sample_physics(config, np.random.default_rng(1), np.full(512, 0.1))
    assert physics.scale.min() >= 0.8 and physics.scale.max() <= 1.2


def test_same_generator_state_gives_the_same_samples() -> None:
    config = ObjectRandomization()
    a = sample_physics(config, np.random.default_rng(5), np.full(4, 0.1))
    b = sample_physics(config, np.random.default_rng(5), np.full(4, 0.1))
    c = sample_physics(config, np.random.default_rng(6), np.full(4, 0.1))
    assert np.array_equal(a.mass, b.mass) and np.array_equal(a.scale, b.scale)
    assert not np.array_equal(a.mass, c.mass)


@pytest.mark.parametrize(
    "bad",
    [
        dict(mass=(0.5, 0.1)),
        dict(friction=(-0.1, 1.0)),
        dict(restitution=(0.0, 1.5)),
        dict(radius=(0.0, 0.1)),
    ],
)
def test_invalid_ranges_are_rejected(bad: dict) -> None:
    with pytest.raises(ValueError):
        ObjectRandomization(**bad)


def test_max_rule_frictions_give_physx_averages_for_robot_object_and_object_scene() -> None:
    """MuJoCo takes the larger of two geoms' frictions; the authors' PhysX averages them. The
    per-geom values must make max() equal the averages the authors trained with."""
    rng = np.random.default_rng(0)
    hand, obj = rng.uniform(1.0, 1.5, 64), rng.uniform(0.2, 1.0, 64)
    scene = rng.uniform(0.2, 0.6, 64)
    robot_geom, object_geom, scene_geom = max_rule_frictions(hand, obj, scene)
    np.testing.assert_allclose(np.maximum(robot_geom, object_geom), (hand + obj) / 2)
    np.testing.assert_allclose(np.maximum(object_geom, scene_geom), (obj + scene) / 2)


def test_the_sims_robot_object_contacts_have_the_averaged_friction() -> None:
    """In the batched model of a reset VectorEnv: the arm's geoms, the object's and the
    scene's frictions combine (max) to the average of the sampled hand and object
    coefficients, which the privileged physics parameters report; the hand coefficient
    spans U(1.0, 1.5) (it was MuJoCo's default 1.0 for every episode)."""
    env = VectorEnv(SimConfig(num_envs=16, num_objects=2, nthread=1))
    observation = env.reset(seed=0)
    params = dict(zip(PHYSICS_PARAM_NAMES, observation.physics_params.T, strict=True))
    friction = env.physics.fields["geom_friction"][..., 0]  # (B, ngeom)
    robot = friction[:, env.physics.robot_geoms]  # (B, G)
    obj = friction[:, env.world.object_geoms].max(-1)  # (B,)
    scene = friction[:, env.world.cuboid_geoms]  # (B, 16)
    average = (params["robot_friction"] + params["object_friction"]) / 2
    combined = np.maximum(robot, obj[:, None])  # (B, G)
    expected = np.broadcast_to(average[:, None], combined.shape)
    np.testing.assert_allclose(combined, expected, rtol=1e-6)
    scene_average = (params["scene_friction"] + params["object_friction"]) / 2
    np.testing.assert_allclose(np.maximum(scene, obj[:, None]).mean(-1), scene_average, rtol=1e-6)
    assert params["robot_friction"].min() >= 1.0 and params["robot_friction"].max() <= 1.5
    assert np.ptp(params["robot_friction"]) > 0.2
