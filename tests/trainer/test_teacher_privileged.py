"""scripts/teacher_privileged.py measures what a teacher's privileged inputs are worth (its
full run, nine evaluations of a student card's 256 episodes, is docs/trainer.md's DAgger
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
