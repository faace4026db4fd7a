"""Batched physics: per-environment scenes, objects and gains really reach MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from hamnet.fr3 import limits as fr3_limits
from hamnet.sim import robot_init
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.objects.library import ObjectSet
from hamnet.sim.physics import BatchPhysics
from hamnet.sim.scene import sample_scenes
from hamnet.sim.scene_config import SceneConfig
from hamnet.sim.world import build_world
from hamnet.task.physics import PHYSICS_PARAM_NAMES

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])

FOLDED = np.array([0.0, -1.5, 0.0, -2.8, 0.0, 1.5, 0.78])
"""Arm folded up and back, out of the way of anything on the table."""


@pytest.fixture(scope="module")
def world():
    return build_world(ObjectSet.procedural(6, seed=0))


def physics_with_scenes(world, num_envs: int, seed: int = 0):
    physics = BatchPhysics(world, num_envs, nthread=2)
    # No ceilings: objects are dropped from above, where a ceiling would catch them.
    config = SceneConfig(p_ceiling=0.0)
    scenes = sample_scenes(np.random.default_rng(seed), np.full(num_envs, 0.08), config)
    envs = np.arange(num_envs)
    physics.set_scene(envs, scenes.centre, scenes.quat, scenes.half_extent, scenes.friction)
    solref = np.tile([0.02, 1.0], (num_envs, 1))
    objects = envs % len(world.objects)
    physics.set_object(envs, objects, np.full(num_envs, 0.3), np.full(num_envs, 0.7), solref)
    kp = np.full((num_envs, 7), 200.0)
    physics.set_gains(kp, 2.0 * np.sqrt(kp), np.tile(fr3_limits.FR3.tau_max, (num_envs, 1)))
    return physics, scenes, envs


def hold(physics, q: np.ndarray, steps: int) -> None:
    for _ in range(steps):
        physics.step(np.repeat(q[:, None, :], 8, axis=1), substeps=5)


def test_each_environment_object_rests_on_its_own_table(world) -> None:
    """Each environment has its own table height and object: an object dropped over the
    table centre must come to rest just above that environment's table top (on a plate at
    most), never fall through a resized box, and never be flung away."""
    num_envs = 12
    physics, scenes, envs = physics_with_scenes(world, num_envs)
    above = np.stack([scenes.centre[:, 0, 0], scenes.centre[:, 0, 1], scenes.table_top + 0.3], 1)
    quat = np.stack([world.objects[i].orientations[0] for i in envs % len(world.objects)])
    physics.set_state(envs, np.tile(FOLDED, (num_envs, 1)), above, quat)
    hold(physics, np.tile(FOLDED, (num_envs, 1)), 15)
    height = physics.qpos[:, world.object_qpos[2]] - scenes.table_top  # (B,)
    assert np.all(height > 0.0) and np.all(height < 0.3), height
    # At rest, or rolling slowly down a ramp: never flung by a bad contact.
    speed = np.linalg.norm(physics.qvel[:, world.object_dof[:3]], axis=1)
    assert np.all(speed < 0.2), speed
    xy = physics.qpos[:, world.object_qpos[:2]] - scenes.centre[:, 0, :2]
    assert np.all(np.abs(xy) <= scenes.half_extent[:, 0, :2] + 0.05)


def test_every_library_mesh_has_the_hull_data_collision_needs(world) -> None:
    """MuJoCo builds hull graphs and polygons only for meshes a colliding geom names; the
    non-colliding catalogue once left every object but the first without them."""
    model = world.model
    assert np.all(model.mesh_graphadr >= 0) and np.all(model.mesh_polynum > 0)


def test_every_library_object_stays_where_it_is_placed_at_rest(world) -> None:
    """An object swapped into the live body (all but library object 0) used to collide with
    one contact at the wrong depth: set at its resting height on a flat table it sank 1-6 cm
    and rocked. Each object, at rest in its most likely pose, must stay within 3 mm."""
    num_envs = len(world.objects)
    physics = BatchPhysics(world, num_envs, nthread=2)
    config = SceneConfig(p_top_plate=0.0, p_wall=0.0, p_ceiling=0.0)  # flat tables
    scenes = sample_scenes(np.random.default_rng(0), np.full(num_envs, 0.08), config)
    envs = np.arange(num_envs)
    physics.set_scene(envs, scenes.centre, scenes.quat, scenes.half_extent, scenes.friction)
    solref = np.tile([0.02, 1.0], (num_envs, 1))
    physics.set_object(envs, envs, np.full(num_envs, 0.3), np.full(num_envs, 0.7), solref)
    stable = world.objects.stable_table()
    height = scenes.table_top + stable.resting_heights[:, 0]  # (B,), m
    placed = np.column_stack([scenes.centre[:, 0, :2], height])  # (B, 3), m
    physics.set_state(envs, np.tile(FOLDED, (num_envs, 1)), placed, stable.orientations[:, 0])
    hold(physics, np.tile(FOLDED, (num_envs, 1)), 5)
    moved = np.linalg.norm(physics.qpos[:, world.object_qpos[:3]] - placed, axis=1)  # (B,), m
    assert np.all(moved < 0.003), moved


def test_batch_matches_each_environment_simulated_alone(world) -> None:
    """Per-simulation fields must make environment i exactly the model `get_model(i)`:
    stepping that model alone with the same references gives the same state."""
    num_envs = 3
    physics, scenes, envs = physics_with_scenes(world, num_envs, seed=3)
    above = np.stack([scenes.centre[:, 0, 0], scenes.centre[:, 0, 1], scenes.table_top + 0.2], 1)
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (num_envs, 1))
    start = np.tile(fr3_limits.Q_HOME, (num_envs, 1))
    physics.set_state(envs, start, above, quat)
    q_ref = start + 0.1  # (B, J)
    hold(physics, q_ref, 3)
    for env in envs:
        model = physics.batch.get_model(int(env))
        data = mujoco.MjData(model)
        data.qpos[world.robot_qpos] = start[env]
        data.qpos[world.object_qpos[:3]] = above[env]
        data.qpos[world.object_qpos[3:]] = quat[env]
        data.ctrl[:] = q_ref[env]
        mujoco.mj_forward(model, data)
        for _ in range(3 * 40):
            mujoco.mj_step(model, data)
        np.testing.assert_allclose(physics.qpos[env], data.qpos, atol=1e-9)


def test_gains_and_torque_clip_are_per_environment(world) -> None:
    num_envs = 2
    physics, scenes, envs = physics_with_scenes(world, num_envs)
    lifted = np.stack([scenes.centre[:, 0, 0], scenes.centre[:, 0, 1], scenes.table_top + 0.2], 1)
    quat = np.tile([1.0, 0, 0, 0], (num_envs, 1))
    physics.set_state(envs, np.tile(FOLDED, (num_envs, 1)), lifted, quat)
    kp = np.full((num_envs, 7), 200.0)
    tau_limit = np.array([fr3_limits.FR3.tau_max, np.full(7, 1.5)])
    physics.set_gains(kp, 2.0 * np.sqrt(kp), tau_limit)
    target = np.tile(FOLDED, (num_envs, 1))
    target[:, 0] += 0.3  # turn about the base: free motion, no gravity load
    physics.step(np.repeat(target[:, None, :], 8, axis=1), substeps=5)
    force = physics.bind("actuator_force")  # (B, J), impedance part, clipped
    assert np.all(np.abs(force[1]) <= 1.5 + 1e-9) and np.abs(force[0, 0]) > 1.5
    hold(physics, target, 9)
    error = np.abs(physics.qpos[:, world.robot_qpos[0]] - target[:, 0])  # (B,)
    assert error[0] < 0.01 < error[1]  # clipped: 1.5 N m against 1.137 N m of friction, lags


def test_a_reset_arm_feels_no_constraint_force_but_contacts(world) -> None:
    """The joints have Coulomb friction (a constraint in MuJoCo). A reset that left the
    impedance reference elsewhere would push every joint against it, and the start check
    (`robot_init.arm_in_contact`, which reads the arm's constraint forces) would reject every
    start: all near starts fell back to the retracted pose. Free arm: no force; paddle in
    the table: a force."""
    num_envs = 2
    physics, scenes, envs = physics_with_scenes(world, num_envs)
    hold(physics, np.tile(FOLDED + 0.3, (num_envs, 1)), 1)  # a reference far from the start
    lifted = np.stack([scenes.centre[:, 0, 0], scenes.centre[:, 0, 1], scenes.table_top + 0.3], 1)
    quat = np.tile([1.0, 0, 0, 0], (num_envs, 1))
    physics.set_state(envs, np.tile(FOLDED, (num_envs, 1)), lifted, quat)
    np.testing.assert_array_equal(physics.ctrl, np.tile(FOLDED, (num_envs, 1)))
    assert not robot_init.arm_in_contact(physics, envs).any()
    reaching_down = np.array([0.0, 1.2, 0.0, -0.3, 0.0, 1.5, 0.78])  # paddle far below the top
    physics.set_state(envs[:1], reaching_down[None], lifted[:1], quat[:1])
    assert robot_init.arm_in_contact(physics, envs).tolist() == [True, False]


def test_joint_dynamics_are_scaled_per_environment(world) -> None:
    """Each environment's armature, damping and friction are the model file's times its own
    factors, and the armature reaches the dynamics: a free joint-1 swing under the same
    torque is slower with more armature."""
    num_envs = 3
    physics, scenes, envs = physics_with_scenes(world, num_envs)
    scale = np.array([[0.7, 0.5, 0.5], [1.0, 1.0, 1.0], [1.3, 2.0, 1.5]])  # (B, 3)
    physics.set_joint_dynamics(envs, scale)
    dofs = world.robot_dof
    for env in envs:
        model = physics.batch.get_model(int(env))
        for column, name in enumerate(("dof_armature", "dof_damping", "dof_frictionloss")):
            expected = getattr(world.model, name)[dofs] * scale[env, column]
            np.testing.assert_allclose(getattr(model, name)[dofs], expected)
    lifted = np.stack([scenes.centre[:, 0, 0], scenes.centre[:, 0, 1], scenes.table_top + 0.2], 1)
    physics.set_state(envs, np.tile(FOLDED, (num_envs, 1)), lifted, np.tile(IDENTITY, (3, 1)))
    kp = np.full((num_envs, 7), 200.0)
    physics.set_gains(kp, 2.0 * np.sqrt(kp), np.tile(fr3_limits.FR3.tau_max, (num_envs, 1)))
    target = np.tile(FOLDED, (num_envs, 1))
    target[:, 0] += 0.3
    physics.step(np.repeat(target[:, None, :], 8, axis=1), substeps=1)  # 20 ms
    moved = physics.qpos[:, world.robot_qpos[0]] - FOLDED[0]  # (B,)
    assert moved[0] > moved[1] > moved[2] > 0.0


def test_episodes_report_their_joint_dynamics_factors() -> None:
    """The drawn factors are within the configured ranges, differ between environments,
    are written into the batch and are reported as columns of the physics parameters."""
    config = SimConfig(num_envs=8, nthread=1)
    env = VectorEnv(config)
    observation = env.reset(seed=4)
    params = dict(zip(PHYSICS_PARAM_NAMES, observation.physics_params.T, strict=True))
    ranges = config.joint_dynamics
    dofs = env.world.robot_dof
    for name, field, bounds in (
        ("joint_armature_scale", "dof_armature", ranges.armature),
        ("joint_damping_scale", "dof_damping", ranges.damping),
        ("joint_friction_scale", "dof_frictionloss", ranges.friction_scale),
    ):
        assert ((params[name] >= bounds[0]) & (params[name] <= bounds[1])).all()
        assert np.ptp(params[name]) > 0.05
        written = env.physics.fields[field][:, dofs] / getattr(env.world.model, field)[dofs]
        np.testing.assert_allclose(written, np.tile(params[name][:, None], (1, 7)), rtol=1e-6)
