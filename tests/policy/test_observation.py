"""Observation assembly: the spec's widths, the previous action in both networks' inputs,
6D rotations by hand, the relative goal, and the student's estimated pose."""

from __future__ import annotations

import math

import pytest
import torch

from hamnet.policy.observation import (
    ObservationSpec,
    PoseNoiseConfig,
    assemble,
    estimated_pose,
    pose_9d,
    relative_goal,
)
from tests.policy.inputs import random_action, random_robot

GROUPS = ("context", "base", "scene_query", "object_query")


@pytest.mark.parametrize("privileged", [True, False])
def test_widths_match_the_assembled_pieces(privileged: bool) -> None:
    spec = ObservationSpec(privileged=privileged)
    observation = assemble(random_robot(3), random_action(3), spec)
    for group in GROUPS:
        assert getattr(observation, group).shape == (3, spec.width(group)), group


def test_authors_widths_by_hand() -> None:
    """rss_train.yaml:290-313: context 5+15+9+21+9+14 (our physics block is 6 wide), base
    15+9+21+9+14 = 68; the object query object+goal+hand = 33, the scene query 14+15."""
    spec = ObservationSpec()
    assert spec.pieces["object_state"] == 15 and spec.pieces["previous_action"] == 21
    assert spec.width("base") == 68 and spec.width("object_query") == 33
    assert spec.width("scene_query") == 29
    assert spec.width("context") == spec.pieces["physics_params"] + 68


@pytest.mark.parametrize("privileged", [True, False])
def test_previous_action_reaches_the_modulation_and_the_base_inputs(privileged: bool) -> None:
    spec = ObservationSpec(privileged=privileged)
    robot = random_robot(2)
    one, other = (assemble(robot, random_action(2, seed), spec) for seed in (0, 1))
    assert not torch.allclose(one.context, other.context)
    assert not torch.allclose(one.base, other.base)
    torch.testing.assert_close(one.object_query, other.object_query)


def test_student_never_sees_privileged_inputs() -> None:
    robot = random_robot(2)
    poisoned = type(robot)(**{**robot.__dict__, "object_velocity": None, "physics_params": None})
    student = ObservationSpec(privileged=False)
    action = random_action(2)
    torch.testing.assert_close(assemble(poisoned, action, student).context,
                               assemble(robot, action, student).context)  # fmt: skip
    with pytest.raises(ValueError, match="privileged block"):
        assemble(poisoned, action, ObservationSpec())


def test_student_goal_is_relative_to_the_estimated_pose() -> None:
    """Paper: the student's goal is relative to the pose estimator's object pose."""
    robot = random_robot(2)
    observation = assemble(robot, random_action(2), ObservationSpec(privileged=False))
    goal = relative_goal(robot.object_pose, robot.goal_pose)  # (B, 9)
    torch.testing.assert_close(observation.base[:, 9:18], goal)
    torch.testing.assert_close(observation.base[:, :9], pose_9d(robot.object_pose))


def test_estimated_pose_errors_have_the_configured_spread() -> None:
    pose = random_robot(20_000).object_pose
    noise = PoseNoiseConfig(position_std=0.01, rotation_std=0.05)
    noisy = estimated_pose(pose, noise, torch.Generator().manual_seed(0))
    position_std = (noisy[:, :3] - pose[:, :3]).std()
    assert abs(position_std - 0.01) < 5e-4
    dot = (noisy[:, 3:] * pose[:, 3:] / pose[:, 3:].norm(dim=-1, keepdim=True)).sum(-1).abs()
    angle = 2 * torch.arccos(dot.clamp(max=1.0))  # |rotation vector|: Maxwell, rms sqrt(3) std
    assert abs(angle.square().mean().sqrt() - math.sqrt(3) * 0.05) < 3e-3
    torch.testing.assert_close(noisy[:, 3:].norm(dim=-1), torch.ones(20_000))


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
