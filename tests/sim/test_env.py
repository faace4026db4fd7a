"""`VectorEnv`: the sim's in-process core, stepped with real MuJoCo."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hamnet.fr3 import limits as fr3_limits
from hamnet.messages.safe_command import Command
from hamnet.sim.config import SimConfig
from hamnet.sim.curriculum import CurriculumValues
from hamnet.sim.env import OBJECT_POINTS, VectorEnv
from hamnet.sim.placement import PlacementConfig
from hamnet.sim.robot_init import RETRACTED
from hamnet.sim.task_config import TaskConfig
from hamnet.sim.termination import Reason
from hamnet.task.physics import PHYSICS_PARAM_NAMES
from hamnet.task.rewards import REWARD_NAMES

B = 4


def make_env(**overrides) -> VectorEnv:
    return VectorEnv(replace(SimConfig(num_envs=B, num_objects=3, nthread=1), **overrides))


def hold(observation, kp: float = 100.0) -> Command:
    """Hold the current joint positions."""
    q = observation.q.astype(np.float64)  # (B, J)
    gains = np.full_like(q, kp)
    return Command(
        q_ref=np.repeat(q[:, None, :], 8, axis=1),
        kp=gains,
        kd=2.0 * np.sqrt(gains),
        tau_limit=np.tile(fr3_limits.FR3.tau_max, (len(q), 1)),
    )


@pytest.fixture(scope="module")
def env() -> VectorEnv:
    return make_env()


def test_observations_and_results_have_the_contract_shapes(env: VectorEnv) -> None:
    observation = env.reset(seed=1)
    result = env.step(hold(observation))
    o = result.observation
    shapes = {
        "q": (B, 7), "dq": (B, 7), "tau": (B, 7), "ee_pos_rot6d": (B, 9), "goal_pose": (B, 7),
        "object_pose": (B, 7), "object_velocity": (B, 6),
        "physics_params": (B, len(PHYSICS_PARAM_NAMES)),
    }  # fmt: skip
    for name, shape in shapes.items():
        value = getattr(o, name)
        assert value.shape == shape and value.dtype == np.float32 and np.isfinite(value).all(), name
    assert result.reward_terms.shape == (B, len(REWARD_NAMES))
    assert np.isfinite(result.reward_terms).all()
    for flags in (result.terminated, result.truncated, result.success):
        assert flags.shape == (B,) and flags.dtype == bool
    rotation = o.ee_pos_rot6d[:, 3:].reshape(B, 2, 3)
    np.testing.assert_allclose(np.linalg.norm(rotation, axis=2), 1.0, atol=1e-5)


def test_same_seed_same_episodes_and_trajectories() -> None:
    first, second = make_env(), make_env()
    a, b = first.reset(seed=5), second.reset(seed=5)
    for _ in range(3):
        a = first.step(hold(a)).observation
        b = second.step(hold(b)).observation
    for name in ("q", "object_pose", "goal_pose", "physics_params"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_array_equal(first.scene_arrays["centre"], second.scene_arrays["centre"])
    other = make_env()
    c = other.reset(seed=6)
    assert not np.array_equal(c.goal_pose, a.goal_pose)


def test_objects_start_at_rest_on_the_scene(env: VectorEnv) -> None:
    """Placements are on horizontal surfaces, clear of walls: a held arm leaves them put."""
    observation = env.reset(seed=2)
    start = observation.object_pose[:, :3].copy()
    for _ in range(5):
        observation = env.step(hold(observation)).observation
    moved = np.linalg.norm(observation.object_pose[:, :3] - start, axis=1)
    assert np.all(moved < 0.02), moved


FOLDED = np.array([0.0, -1.5, 0.0, -2.8, 0.0, 1.5, 0.78])
"""Arm folded up and back, out of the way of anything on the table."""


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_drawn_start_and_goal_pose_stays_put(seed: int) -> None:
    """Two bugs let drawn poses move on their own: episodes used placements that
    `sample_placements` had marked invalid (unchecked candidates overhanging a plate, which
    slid 0.19 m off it), and objects other than the world's first collided without hull
    data (sinking 1-6 cm). Over many environments, each start and goal pose, held for
    0.5 s with the arm folded away, must move less than 1 cm."""
    num_envs = 32
    env = VectorEnv(SimConfig(num_envs=num_envs, num_objects=6, nthread=2))
    observation = env.reset(seed=seed)
    start = observation.object_pose.astype(np.float64)  # (B, 7)
    goal = np.concatenate([env.goal_pos, env.goal_quat], axis=1)  # (B, 7)
    folded = np.tile(FOLDED, (num_envs, 1))  # (B, J)
    ids = np.arange(num_envs)
    for pose in (start, goal):
        env.physics.set_state(ids, folded, pose[:, :3], pose[:, 3:])
        for _ in range(5):
            env.physics.step(np.repeat(folded[:, None, :], 8, axis=1), substeps=5)
        moved = np.linalg.norm(env.physics.qpos[:, env.world.object_qpos[:3]] - pose[:, :3], axis=1)
        assert np.all(moved < 0.01), moved


def test_an_object_that_finds_no_placement_fails_loudly() -> None:
    """An environment whose placement failed in every scene it was given must not start
    from the unchecked candidate: no start lies 10 m or 4 rad from its goal."""
    once = PlacementConfig(
        max_scene_draws=1, min_position_separation=10.0, min_orientation_separation=4.0
    )
    env = VectorEnv(SimConfig(num_envs=32, num_objects=3, nthread=1, placement=once))
    with pytest.raises(RuntimeError, match="no valid placement"):
        env.reset(seed=0)


def test_dropped_object_terminates_and_the_environment_starts_a_new_episode(env: VectorEnv) -> None:
    observation = env.reset(seed=3)
    ids = observation.episode_ids.copy()
    qpos = env.physics.qpos
    qpos[1, env.world.object_qpos[:3]] = [0.5, 1.0, -0.35]  # on the floor beside the table
    env.physics.batch.forward([1])
    result = env.step(hold(observation))
    assert result.terminated[1] and not result.success[1] and result.reason[1] == Reason.DROPPED
    assert not result.terminated[[0, 2, 3]].any()
    assert result.episode_ids[1] == ids[1]  # the transition belongs to the old episode
    assert result.observation.episode_ids[1] > ids.max()  # the observation to the new one
    assert result.observation.episode_step[1] == 0 and result.reset_ids.tolist() == [1]


def test_final_observation_keeps_the_state_that_ended_an_episode(env: VectorEnv) -> None:
    """The value of a truncated episode is bootstrapped from its last state: if
    `final_observation` held the new episode's first state (as `observation` does), the
    object would not be where the step left it."""
    observation = env.reset(seed=3)
    env.physics.qpos[1, env.world.object_qpos[:3]] = [0.5, 1.0, -0.35]  # beside the table
    env.physics.batch.forward([1])
    result = env.step(hold(observation))
    final, first = result.final_observation, result.observation
    assert result.reset_ids.tolist() == [1]
    assert final.object_pose[1, 2] < -0.3 and first.object_pose[1, 2] > -0.25
    assert final.episode_ids[1] == result.episode_ids[1] != first.episode_ids[1]
    for name in ("q", "object_pose", "episode_ids"):
        np.testing.assert_array_equal(
            getattr(final, name)[[0, 2, 3]], getattr(first, name)[[0, 2, 3]]
        )


def test_scenes_describe_the_current_episodes(env: VectorEnv) -> None:
    observation = env.reset(seed=5)
    scenes = env.scenes(np.array([2, 0]))
    assert scenes.env_ids.tolist() == [2, 0]
    np.testing.assert_array_equal(scenes.episode_ids, observation.episode_ids[[2, 0]])
    np.testing.assert_array_equal(scenes.start_pose, observation.object_pose[[2, 0]])
    np.testing.assert_array_equal(scenes.goal_pose, observation.goal_pose[[2, 0]])
    np.testing.assert_array_equal(scenes.object_scale, observation.physics_params[[2, 0], 5])
    assert scenes.cuboid_centre.shape[0] == 2 and scenes.cuboid_active[:, 0].all()  # the table
    assert scenes.object_points.shape == (2, OBJECT_POINTS, 3)
    assert len(scenes.object_ids) == 2 and scenes.env_code.shape == (2, 25)
    moved = env.step(hold(observation)).observation  # the start pose stays the episode's
    still = moved.episode_ids[[2, 0]] == observation.episode_ids[[2, 0]]
    np.testing.assert_array_equal(
        env.scenes(np.array([2, 0])).start_pose[still], scenes.start_pose[still]
    )
    assert len(env.scenes().env_ids) == B


def test_object_at_its_goal_succeeds_and_earns_the_success_reward(env: VectorEnv) -> None:
    goal = env.reset(seed=4).goal_pose.astype(np.float64)
    # Arm retracted: a near start may hold the paddle where the goal pose puts the object.
    env.physics.set_state(np.array([2]), RETRACTED[None], goal[2:3, :3], goal[2:3, 3:])
    result = env.step(hold(env.observe()))
    assert result.success[2] and result.terminated[2] and result.reason[2] == Reason.SUCCESS
    assert result.reward_terms[2, REWARD_NAMES.index("success")] == pytest.approx(1.0)
    assert result.reward_terms[~result.success, REWARD_NAMES.index("success")].sum() == 0.0


def test_timeout_truncates_every_episode_without_terminating_it() -> None:
    short = make_env(task=TaskConfig(timeout=3))
    observation = short.reset(seed=0)
    first_ids = observation.episode_ids.copy()
    for _ in range(3):
        result = short.step(hold(observation))
        observation = result.observation
    # Episodes that lasted the whole 3 steps (none ended early by success or a drop).
    lasted = result.episode_ids == first_ids  # (B,)
    assert lasted.any()
    assert result.truncated[lasted].all() and not result.terminated[lasted].any()
    assert set(result.observation.episode_ids).isdisjoint(first_ids)


def test_near_starts_put_the_paddle_beside_the_object_without_touching_anything() -> None:
    near = make_env()
    near.set_schedule(CurriculumValues(p_near_init=1.0, p_tight=0.0))
    observation = near.reset(seed=8)
    gap = np.linalg.norm(observation.ee_pos_rot6d[:, :3] - observation.object_pose[:, :3], axis=1)
    assert np.median(gap) < 0.25, gap
    ncon = near.physics.bind("ncon")
    for env_index in range(B):
        data = near.physics.batch.get_data(env_index)
        bodies = near.world.model.geom_bodyid[[data.contact.geom1, data.contact.geom2]]
        arm_contacts = np.isin(bodies, near.world.robot_bodies).any(axis=0).sum()
        assert (
            arm_contacts == 0
            or (observation.q[env_index] == fr3_limits.Q_HOME.astype(np.float32)).all()
        )
    assert ncon.shape == (B,)


def test_object_points_cover_each_sized_object_surface(env: VectorEnv) -> None:
    points = env.object_points  # (N, P, 3)
    assert points.shape == (len(env.library.objects), OBJECT_POINTS, 3)
    for asset, cloud in zip(env.library.objects, points, strict=True):
        low, high = asset.bbox
        assert (cloud >= low - 1e-5).all() and (cloud <= high + 1e-5).all(), asset.name
        # Uniform on the surface: the cloud spans the object's box on every axis.
        np.testing.assert_allclose(cloud.min(0), low, atol=0.25 * (high - low).max())
        np.testing.assert_allclose(cloud.max(0), high, atol=0.25 * (high - low).max())
