"""scripts/teacher_privileged.py measures what a teacher's privileged inputs are worth (its
full run, eleven evaluations of a student's result's 256 episodes, is docs/trainer.md's DAgger
diagnosis): the velocity it derives from poses must be the motion they show."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from tests.script_modules import load

teacher_privileged = load("scripts/teacher_privileged.py")

PERIOD = 0.05
LINEAR = np.array([0.2, -0.1, 0.0])  # m/s
YAW_RATE = 0.5  # rad/s about z


def moving_object(step: int, episode_step: int) -> SimpleNamespace:
    """One environment's object `step` periods into a constant linear and yaw motion; the
    velocity field holds garbage the edit must overwrite."""
    half = 0.5 * YAW_RATE * PERIOD * step
    pose = np.concatenate([LINEAR * PERIOD * step, [np.cos(half), 0.0, 0.0, np.sin(half)]])
    return SimpleNamespace(
        object_pose=pose[None].astype(np.float32),
        object_velocity=np.full((1, 6), 9.0, np.float32),
        episode_step=np.array([episode_step], np.int32),
    )


def test_difference_velocity_recovers_a_constant_motion_and_restarts_with_each_episode() -> None:
    edit = teacher_privileged.difference_velocity(PERIOD, span=4)
    expected = np.concatenate([LINEAR, [0.0, 0.0, YAW_RATE]])
    seen = []
    for step in range(6):
        observation = moving_object(step, episode_step=step)
        edit(observation)
        seen.append(observation.object_velocity[0])
    np.testing.assert_array_equal(seen[0], np.zeros(6))  # no history at an episode's start
    for velocity in seen[1:]:  # 1, 2, 3 then 4 steps back
        np.testing.assert_allclose(velocity, expected, rtol=1e-3, atol=1e-5)  # small-angle form
    restarted = moving_object(6, episode_step=0)
    edit(restarted)
    np.testing.assert_array_equal(restarted.object_velocity[0], np.zeros(6))


def still_object(position: np.ndarray, environments: int, episode_step: int) -> SimpleNamespace:
    """`environments` copies of an unturned object at `position`."""
    pose = np.concatenate([position, [1.0, 0.0, 0.0, 0.0]])
    return SimpleNamespace(
        object_pose=np.tile(pose, (environments, 1)).astype(np.float32),
        episode_step=np.full(environments, episode_step, np.int32),
    )


def test_averaged_estimate_averages_the_episodes_own_readings_only() -> None:
    noise = teacher_privileged.PoseNoiseConfig(position_std=0.01, rotation_std=0.075)
    edit = teacher_privileged.averaged_estimate(noise, span=4, seed=0)
    errors = []
    for step in range(4):
        observation = still_object(np.zeros(3), environments=4096, episode_step=step)
        edit(observation)
        errors.append(observation.object_pose[:, 0].std())
    # one reading, then the mean of 2, 3 and 4: the spread falls as 1 / sqrt(readings)
    np.testing.assert_allclose(errors, 0.01 / np.sqrt([1, 2, 3, 4]), rtol=0.05)
    np.testing.assert_allclose(np.linalg.norm(observation.object_pose[:, 3:], axis=1), 1.0)
    moved = still_object(np.array([0.3, 0.0, 0.0]), environments=4096, episode_step=0)
    edit(moved)  # a new episode elsewhere: no reading of the last one may pull it back
    assert abs(moved.object_pose[:, 0].mean() - 0.3) < 0.001
    np.testing.assert_allclose(moved.object_pose[:, 0].std(), 0.01, rtol=0.05)
