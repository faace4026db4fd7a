"""The policy service's messages: RobotState, PerceptionTokens, Scene and Transition decoded
(`hamnet.messages`) with the fields and widths the policy reads, and its answer encoded as a
PolicyAction (`encode_action`). Pure functions, tested without a session; a malformed payload
raises `PayloadError` (the inbox counts and drops it).
"""

from __future__ import annotations

import numpy as np
import torch

from hamnet.messages import robot_state, scene, tokens, transition
from hamnet.messages.robot_state import StateIn
from hamnet.messages.tokens import TokensIn
from hamnet.messages.transition import TransitionIn
from hamnet.policy.observation import RobotObservation
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.sim_pb2 import RobotState, Scene, Transition
from hamnet.runtime.tensor import PayloadError
from hamnet.sim.rewards import REWARD_NAMES

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
    reads = POLICY_READS if privileged else (*POLICY_READS, "object_pose_estimate")
    state = robot_state.decode(message, required=reads)
    if privileged:
        if state.privileged is None:
            raise PayloadError("missing", "RobotState.privileged is needed by a teacher")
        width = state.privileged.physics_params.shape[1]
        if width != physics_params:
            raise PayloadError("shape", f"PrivilegedState.physics_params: {width} parameters, "
                                        f"the policy reads {physics_params}")  # fmt: skip
    return state


def robot_observation(state: StateIn, privileged: bool) -> RobotObservation:
    """What the policy observes of a state decoded by `decode_state`, as CPU tensors: a
    teacher's object pose, velocity and physics parameters are the privileged block's, a
    student's object pose is the estimate."""
    extra = {"object_pose": state.object_pose_estimate}
    if privileged:
        extra = {name: getattr(state.privileged, name)
                 for name in ("object_pose", "object_velocity", "physics_params")}  # fmt: skip
    arrays = {"q": state.q, "dq": state.dq, "ee_pos_rot6d": state.ee_pos_rot6d,
              "goal_pose": state.goal_pose, **extra}  # fmt: skip
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
        raise PayloadError("shape", f"reward terms {list(message.reward_names)}, the critic's "
                                    f"are {list(REWARD_NAMES)}")  # fmt: skip
    return transition.decode(message)
