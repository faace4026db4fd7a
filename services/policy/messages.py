"""The policy service's messages: RobotState, PerceptionTokens, Scene and Transition decoded
into what the policy reads, and its answer encoded as a PolicyAction. Pure functions, tested
without a session; a malformed payload raises `PayloadError` (the inbox counts and drops it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.policy.observation import POSE_WIDTH, VELOCITY_WIDTH, RobotObservation
from hamnet.policy.policy import Action
from hamnet.proto.common_pb2 import Header
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.sim_pb2 import RobotState, Scene, Transition
from hamnet.runtime.tensor import PayloadError, field_array, to_tensor
from hamnet.sim.rewards import REWARD_NAMES


@dataclass(frozen=True)
class StateIn:
    """What the policy reads of RobotState k."""

    run: int
    """The sim's run (`Header.run`)."""
    step: int
    episode_ids: np.ndarray
    """(B,) int64."""
    episode_step: np.ndarray
    """(B,) int32 policy steps since each episode started."""
    robot: RobotObservation


@dataclass(frozen=True)
class TokensIn:
    """PerceptionTokens k."""

    step: int
    episode_ids: np.ndarray
    """(B,) int64."""
    tokens: tuple[torch.Tensor, torch.Tensor, torch.Tensor]
    """Object, local and global tokens, (B, N, D) float32 each."""


def _floats(owner, name: str, shape) -> torch.Tensor:
    """A float32 field as a tensor (one copy out of the read-only wire buffer)."""
    return torch.tensor(field_array(owner, name, np.float32, shape))


def decode_state(message: RobotState, privileged: bool, physics_params: int) -> StateIn:
    """RobotState k: a teacher (`privileged`) reads the privileged block, a student the
    pose estimator's object pose (`object_pose_estimate`), as on the real robot.

    Args:
        physics_params: P, the width of the physics parameters.
    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    q = _floats(message, "q", (None, J))  # (B, J)
    b = len(q)
    if privileged:
        if not message.HasField("privileged"):
            raise PayloadError("missing", "RobotState.privileged is needed by a teacher")
        block = message.privileged
        extra = {
            "object_pose": _floats(block, "object_pose", (b, 7)),
            "object_velocity": _floats(block, "object_velocity", (b, VELOCITY_WIDTH)),
            "physics_params": _floats(block, "physics_params", (b, physics_params)),
        }
    else:
        extra = {"object_pose": _floats(message, "object_pose_estimate", (b, 7))}
    robot = RobotObservation(
        q=q,
        dq=_floats(message, "dq", (b, J)),
        ee_pose=_floats(message, "ee_pose", (b, POSE_WIDTH)),
        goal_pose=_floats(message, "goal_pose", (b, 7)),
        **extra,
    )
    episode_ids = field_array(message, "episode_ids", np.int64, (b,)).copy()
    episode_step = field_array(message, "episode_step", np.int32, (b,)).copy()
    return StateIn(message.header.run, message.header.step, episode_ids, episode_step, robot)


def decode_tokens(message: PerceptionTokens, num_tokens: int, token_dim: int) -> TokensIn:
    """PerceptionTokens k (object, local and global tokens (B, N, D)).

    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    shape = (None, num_tokens, token_dim)
    obj = _floats(message, "object_tokens", shape)
    b = len(obj)
    local = _floats(message, "local_tokens", (b, num_tokens, token_dim))
    whole = _floats(message, "global_tokens", (b, num_tokens, token_dim))
    episode_ids = field_array(message, "episode_ids", np.int64, (b,)).copy()
    return TokensIn(message.header.step, episode_ids, (obj, local, whole))


def decode_scene(message: Scene, env_code_dim: int) -> tuple[np.ndarray, np.ndarray]:
    """(env_ids (K,), env_code (K, 25)) of a Scene."""
    env_ids = field_array(message, "env_ids", np.int32, (None,))
    env_code = field_array(message, "env_code", np.float32, (len(env_ids), env_code_dim))
    return env_ids.copy(), env_code.copy()


@dataclass(frozen=True)
class TransitionIn:
    """Transition k: the outcome of the command that answered state k."""

    step: int
    episode_ids: np.ndarray
    """(B,) int64, before any reset."""
    reward_terms: np.ndarray
    """(B, R) float32, in the order of `REWARD_NAMES`."""
    terminated: np.ndarray
    """(B,) bool."""
    truncated: np.ndarray
    """(B,) bool."""
    success: np.ndarray
    """(B,) bool."""


def decode_transition(message: Transition) -> TransitionIn:
    """Transition k, its reward terms checked against the critic's (`REWARD_NAMES`).

    Raises:
        PayloadError: `missing`, `dtype`, `shape` (other reward terms), `nonfinite`.
    """
    if tuple(message.reward_names) != REWARD_NAMES:
        raise PayloadError("shape", f"reward terms {list(message.reward_names)}, the critic's "
                                    f"are {list(REWARD_NAMES)}")  # fmt: skip
    ids = field_array(message, "episode_ids", np.int64, (None,)).copy()
    b = len(ids)
    flags = {name: field_array(message, name, bool, (b,)).copy()
             for name in ("terminated", "truncated", "success")}  # fmt: skip
    rewards = field_array(message, "reward_terms", np.float32, (b, len(REWARD_NAMES))).copy()
    return TransitionIn(message.header.step, ids, rewards, **flags)


def encode_action(
    step: int, version: int, episode_ids: np.ndarray, action: Action, deterministic: bool
) -> PolicyAction:
    """PolicyAction k: action (B, 21), log_prob (B,), values (B, R), module weights (B, L, M)."""
    message = PolicyAction(
        header=Header(step=step, policy_version=version), deterministic=deterministic
    )
    to_tensor(np.asarray(episode_ids, dtype=np.int64), message.episode_ids)
    for name in ("action", "log_prob", "values", "module_weights"):
        value = getattr(action, name).detach().to("cpu", torch.float32).numpy()
        to_tensor(value, getattr(message, name))
    return message
