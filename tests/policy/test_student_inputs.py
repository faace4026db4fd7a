"""No privileged field reaches the student (issue 15): with the object velocity and the
physics parameters NaN, the student's action is the same finite action as with any other
values there, through the input builder and through the trainer's rollout worker; and the
worker hands a student the pose estimate, never the sim's true pose."""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from hamnet.perception.config import student_clouds
from hamnet.perception.core import Perception
from hamnet.perception.unicorn import UniCORN
from hamnet.policy import inputs as builder
from hamnet.policy.observation import PoseNoiseConfig, RobotObservation, pose_9d
from hamnet.policy.registry import build
from hamnet.safety.config import with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.env import VectorEnv
from hamnet.sim.stages import stage_config
from hamnet.trainer.collection.rollout_worker import RolloutWorker
from tests.policy.inputs import random_robot

B = 2


def with_privileged(robot: RobotObservation, value: float | None) -> RobotObservation:
    """`robot` with object velocity and physics parameters all `value` (None: random)."""
    fill = lambda t: torch.randn_like(t) if value is None else torch.full_like(t, value)
    return dataclasses.replace(
        robot,
        object_velocity=fill(robot.object_velocity),
        physics_params=fill(robot.physics_params),
    )


def builder_action(robot: RobotObservation, noise: PoseNoiseConfig | None) -> torch.Tensor:
    """(B, A) the student's deterministic action on `robot` after a first step."""
    policy = build("student", seed=0).eval()
    carry = builder.initial_carry(policy, B)
    carry = builder.begin_step(carry, torch.zeros(B, dtype=torch.int64), torch.ones(B))
    g = torch.Generator().manual_seed(0)
    tokens = tuple(torch.randn(B, 17, 128, generator=g) for _ in range(3))
    carry, read = builder.observed_state(policy.config, carry, robot, noise, g)
    inputs = builder.policy_inputs(policy.config, carry, read, tokens)
    with torch.no_grad():
        return policy.act(inputs, deterministic=True).action


def test_nan_privileged_fields_leave_the_students_action_unchanged() -> None:
    """Sim path (true pose + the estimator's noise) and real path (the estimate as given):
    NaN, zeros and random values in the privileged fields give one finite action."""
    robot = random_robot(B)
    for noise in (PoseNoiseConfig(), None):
        nan = builder_action(with_privileged(robot, float("nan")), noise)
        assert torch.isfinite(nan).all()
        for other in (0.0, None):
            torch.testing.assert_close(
                nan, builder_action(with_privileged(robot, other), noise), rtol=0, atol=0
            )


def student_worker() -> RolloutWorker:
    env = VectorEnv(stage_config("easy", num_envs=B, num_objects=2, nthread=1))
    safety = SafetyFilter(np.zeros((B, 7)), with_profile("training"))
    torch.manual_seed(0)
    return RolloutWorker(env, Perception(UniCORN(), B, student_clouds()), safety)


def test_the_rollout_worker_gives_a_student_no_privileged_field() -> None:
    """The trainer's in-process path: with the sim's privileged arrays NaN the student acts
    as with their true values, finitely; its object state is the noisy estimate (before the
    worker applied the estimator, the student read the sim's true pose)."""
    policy = build("student", seed=0).eval()
    worker = student_worker()
    true = worker.observation
    nan = dataclasses.replace(
        true,
        object_velocity=np.full_like(true.object_velocity, np.nan),
        physics_params=np.full_like(true.physics_params, np.nan),
    )
    actions = []
    for observation in (nan, true):
        worker.observation, worker.seat.carry = observation, None
        worker.generator.manual_seed(0)
        with torch.no_grad():  # as `collect` acts
            pending = worker.act(policy, env_transitions=0, deterministic=True)
        actions.append(pending.acted.action)
    assert torch.isfinite(actions[0]).all()
    torch.testing.assert_close(actions[0], actions[1], rtol=0, atol=0)
    state = pending.inputs.observation.base
    columns = policy.config.observation.columns("base", "object_state")
    true_pose = pose_9d(torch.as_tensor(true.object_pose, dtype=torch.float32))
    estimate = state[:, columns]  # (B, 9) raw inputs: the policy standardises them itself
    assert not torch.allclose(estimate, true_pose, atol=1e-4)
    assert (estimate[:, :3] - true_pose[:, :3]).abs().max() < 0.1  # 10 sigma of 0.01 m
