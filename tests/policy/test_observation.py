"""Observation assembly: widths, 6D rotations by hand, and the relative goal."""

from __future__ import annotations

import math

import pytest
import torch

from hamnet.policy.observation import assemble, pose_9d, relative_goal, widths
from tests.policy.inputs import random_robot


@pytest.mark.parametrize("privileged", [True, False])
def test_widths_match_the_assembled_pieces(privileged: bool) -> None:
    observation = assemble(random_robot(3), privileged)
    got = (observation.state.shape[1], observation.scene_query.shape[1], observation.object_query.shape[1])
    assert got == widths(privileged)


def test_student_never_sees_privileged_inputs() -> None:
    robot = random_robot(2)
    poisoned = type(robot)(**{**robot.__dict__, "object_pose": None, "object_velocity": None,
                              "physics_params": None})  # fmt: skip
    torch.testing.assert_close(assemble(poisoned, False).state, assemble(robot, False).state)
    with pytest.raises(ValueError, match="privileged block"):
        assemble(poisoned, True)


def test_six_d_of_a_quarter_turn_about_z_by_hand() -> None:
    half = math.sqrt(0.5)
    pose = torch.tensor([[1.0, 2.0, 3.0, half, 0.0, 0.0, half]])  # 90 deg about z
    # R = [[0,-1,0],[1,0,0],[0,0,1]]: first column (0,1,0), second (-1,0,0).
    expected = torch.tensor([[1.0, 2.0, 3.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0]])
    torch.testing.assert_close(pose_9d(pose), expected, atol=1e-6, rtol=0)


def test_goal_equal_to_object_pose_is_the_identity() -> None:
    pose = torch.tensor([[0.3, -0.2, 0.5, 0.5, 0.5, 0.5, 0.5]])
    identity = torch.tensor([[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]])
    torch.testing.assert_close(relative_goal(pose, pose), identity, atol=1e-6, rtol=0)
