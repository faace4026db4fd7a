"""The policy service's messages: RobotState, PerceptionTokens, Scene and Transition decoded
(`hamnet.messages`) with the fields and widths the policy reads, and its answer encoded as a
PolicyAction (`encode_action`). Pure functions, tested without a session; a malformed payload
raises `PayloadError` (the inbox counts and drops it). `decoders` gives the shell the inbox
decoder of each of its inputs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from hamnet.messages import robot_state, scene, tokens, transition
from hamnet.messages.robot_state import StateIn
from hamnet.messages.schedule import decode as decode_schedule
from hamnet.messages.tokens import TokensIn
from hamnet.messages.transition import TransitionIn
from hamnet.policy.config import ModelConfig
from hamnet.policy.observation import RobotObservation
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.sim_pb2 import RobotState, Scene, Transition
from hamnet.proto.trainer_pb2 import Schedule, WeightsAnnouncement
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.tensor import PayloadError
from hamnet.task.rewards import REWARD_NAMES

POLICY_READS = ("episode_ids", "episode_step", "q", "dq", "ee_pos_rot6d", "goal_pose")
"""The RobotState fields every policy reads; a teacher also reads the privileged block, a
student `object_pose_estimate`."""


def decode_state(message: RobotState, privileged: bool, physics_params: int) -> StateIn:
    """RobotState k: a teacher (`privileged`) reads the privileged block, a student the
    pose estimator's object pose (`object_pose_estimate`), as on the real robot.

    Args:
        physics_params: P, the width of the physics parameters.
    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    if not privileged:
        return robot_state.decode(message, required=(*POLICY_READS, "object_pose_estimate"))
    why = "a teacher reads it"
    return robot_state.decode(
        message, required=POLICY_READS, privileged_for=why, physics_params=physics_params
    )


def robot_observation(state: StateIn, privileged: bool) -> RobotObservation:
    """What the policy observes of a state decoded by `decode_state`, as CPU tensors: a
    teacher's object pose, velocity and physics parameters are the privileged block's, a
    student's object pose is the estimate."""
    extra = {"object_pose": state.object_pose_estimate}
    if privileged:
        extra = {
            name: getattr(state.privileged, name)
            for name in ("object_pose", "object_velocity", "physics_params")
        }
    arrays = {
        "q": state.q,
        "dq": state.dq,
        "ee_pos_rot6d": state.ee_pos_rot6d,
        "goal_pose": state.goal_pose,
        **extra,
    }
    return RobotObservation(**{name: torch.from_numpy(value) for name, value in arrays.items()})


def decode_tokens(message: PerceptionTokens, num_tokens: int, token_dim: int) -> TokensIn:
    """PerceptionTokens k (object, local and global tokens (B, N, D)).

    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    return tokens.decode(message, ("episode_ids", *tokens.TOKENS), (num_tokens, token_dim))


def decode_scene(message: Scene, env_code_dim: int) -> tuple[np.ndarray, np.ndarray]:
    """(env_ids (K,), env_code (K, 25)) of a Scene."""
    decoded = scene.decode(message, ("env_code",), env_code_dim=env_code_dim)
    return decoded.env_ids, decoded.env_code


def decode_transition(message: Transition) -> TransitionIn:
    """Transition k, its reward terms checked against the critic's (`REWARD_NAMES`).

    Raises:
        PayloadError: `missing`, `dtype`, `shape` (other reward terms), `nonfinite`.
    """
    if tuple(message.reward_names) != REWARD_NAMES:
        raise PayloadError(
            "shape",
            f"reward terms {list(message.reward_names)}, the critic's are {list(REWARD_NAMES)}",
        )
    return transition.decode(message)


def decoders(model: ModelConfig, rollouts: bool) -> dict[str, Callable[[str, bytes], Any]]:
    """The inbox decoder of each input of a policy serving `model` (`transition` only when
    it publishes `rollouts`), by the input's port name."""
    privileged, physics_params = model.privileged, model.observation.physics_params
    reads: dict[str, tuple[type, Callable[[Any], Any] | None]] = {
        "state": (RobotState, lambda m: decode_state(m, privileged, physics_params)),
        "tokens": (PerceptionTokens, lambda m: decode_tokens(m, model.num_tokens, model.token_dim)),
        "scene": (Scene, lambda m: decode_scene(m, model.env_code_dim)),
        "weights": (WeightsAnnouncement, None),
        "schedule": (Schedule, decode_schedule),
    }
    if rollouts:
        reads["transition"] = (Transition, decode_transition)
    return {name: payload_decoder(*read) for name, read in reads.items()}
