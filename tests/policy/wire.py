"""Contract messages for policy tests: states, tokens, scenes and weights announcements
built from the same random inputs the core tests use."""

from __future__ import annotations

import numpy as np
import torch

from hamnet.policy.policy import Policy
from hamnet.policy.weights import sha256, to_bytes
from hamnet.proto.common_pb2 import Header
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.sim_pb2 import RobotState, Scene
from hamnet.proto.trainer_pb2 import WeightsAnnouncement
from hamnet.runtime.tensor import to_tensor
from tests.policy.inputs import random_robot


def _f32(tensor: torch.Tensor, out) -> None:
    to_tensor(tensor.numpy().astype(np.float32), out)


def state_message(
    step: int, batch: int, episode_ids=None, episode_step=None, run: int = 0
) -> RobotState:
    """RobotState `step` of the sim's `run` with the privileged block and the pose estimate
    (the exact pose, as the sim sends it); random but reproducible per step."""
    robot = random_robot(batch, seed=step)
    message = RobotState(header=Header(step=step, run=run))
    ids = np.zeros(batch, np.int64) if episode_ids is None else np.asarray(episode_ids, np.int64)
    to_tensor(ids, message.episode_ids)
    steps = (
        np.full(batch, step, np.int32)
        if episode_step is None
        else np.asarray(episode_step, np.int32)
    )
    to_tensor(steps, message.episode_step)
    for name in ("q", "dq", "ee_pos_rot6d", "goal_pose"):
        _f32(getattr(robot, name), getattr(message, name))
    for name in ("object_pose", "object_velocity", "physics_params"):
        _f32(getattr(robot, name), getattr(message.privileged, name))
    _f32(robot.object_pose, message.object_pose_estimate)
    return message


def tokens_message(step: int, batch: int, episode_ids=None) -> PerceptionTokens:
    """PerceptionTokens `step` (17 x 128 tokens per cloud)."""
    g = torch.Generator().manual_seed(10_000 + step)
    message = PerceptionTokens(header=Header(step=step))
    ids = np.zeros(batch, np.int64) if episode_ids is None else np.asarray(episode_ids, np.int64)
    to_tensor(ids, message.episode_ids)
    for name in ("object_tokens", "local_tokens", "global_tokens"):
        _f32(torch.randn(batch, 17, 128, generator=g), getattr(message, name))
    return message


def scene_message(env_ids, env_code: np.ndarray) -> Scene:
    """A Scene carrying only what the policy reads (env ids and EnvCode)."""
    message = Scene(header=Header(step=0))
    to_tensor(np.asarray(env_ids, np.int32), message.env_ids)
    to_tensor(env_code.astype(np.float32), message.env_code)
    return message


def announcement(policy: Policy, version: int, data: bytes | None = None) -> WeightsAnnouncement:
    """WeightsAnnouncement of `policy` (or of raw `data`) as `version`."""
    data = to_bytes(policy, version) if data is None else data
    return WeightsAnnouncement(
        header=Header(step=version), version=version, architecture=policy.architecture,
        config_json=policy.config.to_json(), safetensors=data, sha256=sha256(data),
    )  # fmt: skip
