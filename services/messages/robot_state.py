"""RobotState (sim and bridge -> safety, policy, perception, camera, monitor): the sim's
`Observation`, its encoder, and the one decoder every consumer reads states with.

A decoded state holds every field the message carries; each consumer names the fields it
reads (`required`), so a state lacking one is dropped as `missing` where it matters and
accepted where it does not (a camera needs only `q`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.messages.fields import Spec, arrays, batch_size
from hamnet.proto.common_pb2 import Header
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.tensor import PayloadError, to_tensor


@dataclass(frozen=True)
class Observation:
    """Batched state after a sim step (what RobotState carries; `object_pose`,
    `object_velocity` and `physics_params` are the sim-only privileged block)."""

    episode_ids: np.ndarray  # (B,) int64
    episode_step: np.ndarray  # (B,) int32
    q: np.ndarray  # (B, J) rad
    dq: np.ndarray  # (B, J) rad/s
    tau: np.ndarray  # (B, J) N m, actuator torque (gravity compensation included)
    ee_pos_rot6d: np.ndarray  # (B, 9): position (3) + first two rotation columns (6)
    goal_pose: np.ndarray  # (B, 7): position + quaternion wxyz
    object_pose: np.ndarray  # (B, 7), privileged
    object_velocity: np.ndarray  # (B, 6): linear, angular, privileged
    physics_params: np.ndarray  # (B, P), privileged (`hamnet.task.physics.PHYSICS_PARAM_NAMES`)


@dataclass(frozen=True)
class Privileged:
    """RobotState.privileged: simulation-only quantities (teacher inputs)."""

    object_pose: np.ndarray
    """(B, 7) float32 object pose: position (m) and quaternion wxyz."""
    object_velocity: np.ndarray
    """(B, 6) float32 linear (m/s) and angular (rad/s) velocity, world frame."""
    physics_params: np.ndarray
    """(B, P) float32 (`hamnet.task.physics.PHYSICS_PARAM_NAMES`)."""


@dataclass(frozen=True)
class StateIn:
    """RobotState k decoded: float32 arrays as sent; a field the message leaves out is
    None. Cores built on one robot's arrays take it as it is (`StateIn(run, step, q, dq,
    episode_ids, episode_step)`)."""

    run: int
    """The sender's run (`Header.run`): a restarted sim repeats step numbers."""
    step: int
    """k, `Header.step`."""
    q: np.ndarray | None = None
    """(B, J) joint positions, rad."""
    dq: np.ndarray | None = None
    """(B, J) joint velocities, rad/s."""
    episode_ids: np.ndarray | None = None
    """(B,) int64."""
    episode_step: np.ndarray | None = None
    """(B,) int32 policy steps since each episode started (0: it starts in this state)."""
    tau: np.ndarray | None = None
    """(B, J) measured joint torques, N m."""
    ee_pos_rot6d: np.ndarray | None = None
    """(B, 9) end-effector position (m) and first two rotation columns."""
    goal_pose: np.ndarray | None = None
    """(B, 7) object goal: position (m) and quaternion wxyz."""
    object_pose_estimate: np.ndarray | None = None
    """(B, 7) object pose as a pose estimator reports it (what a student reads)."""
    privileged: Privileged | None = None
    """Present in simulation only."""
    stamp_ns: int = 0
    """`Header.stamp_ns`."""


_FIELDS = {
    "episode_ids": Spec(np.int64),
    "episode_step": Spec(np.int32),
    "q": Spec(np.float32, (J,)),
    "dq": Spec(np.float32, (J,)),
    "tau": Spec(np.float32, (J,)),
    "ee_pos_rot6d": Spec(np.float32, (9,)),
    "goal_pose": Spec(np.float32, (7,)),
    "object_pose_estimate": Spec(np.float32, (7,)),
}
_PRIVILEGED = {
    "object_pose": Spec(np.float32, (7,)),
    "object_velocity": Spec(np.float32, (6,)),
    "physics_params": Spec(np.float32, (None,)),
}


def decode(
    message: RobotState,
    num_envs: int | None = None,
    required: Iterable[str] = (),
    privileged_for: str = "",
    physics_params: int | None = None,
) -> StateIn:
    """RobotState k, every field it carries checked against one batch size B: the decoder
    of every consumer, which adds only what is its own (a precision, a row in focus).

    Args:
        num_envs: B; None takes it from the message (episode_ids, else q).
        required: fields that must be set (names of `StateIn`'s arrays).
        privileged_for: why this consumer needs the privileged block, in the `missing`
            error when a state lacks it (a real robot sends none); empty: not needed.
        physics_params: P, the width of the privileged physics parameters this consumer
            reads; None: any.
    Raises:
        PayloadError: `missing` (a required field or block, or a privileged block without
            all three fields), `dtype` (not as documented), `shape` (batch or width),
            `nonfinite`.
    """
    b = num_envs if num_envs is not None else batch_size(message, _FIELDS, ("episode_ids", "q"))
    decoded = arrays(message, _FIELDS, b, required)
    privileged = None
    if message.HasField("privileged"):
        specs = _PRIVILEGED
        if physics_params is not None:
            specs = {**specs, "physics_params": Spec(np.float32, (physics_params,))}
        privileged = Privileged(**arrays(message.privileged, specs, b, specs))
    elif privileged_for:
        raise PayloadError("missing", f"RobotState.privileged is not set: {privileged_for}")
    header = message.header
    return StateIn(
        header.run, header.step, privileged=privileged, stamp_ns=header.stamp_ns, **decoded
    )


def encode(state: StateIn) -> RobotState:
    """RobotState k from every field `state` has (None leaves it out), in the documented
    dtypes: the one encoder of the sim's and the bridge's states. `run` 0 leaves the
    header's run to the publisher."""
    message = RobotState(header=Header(step=state.step, run=state.run))
    for name, spec in _FIELDS.items():
        if (value := getattr(state, name)) is not None:
            to_tensor(np.asarray(value, dtype=spec.dtype), getattr(message, name))
    if state.privileged is not None:
        for name, spec in _PRIVILEGED.items():
            value = np.asarray(getattr(state.privileged, name), dtype=spec.dtype)
            to_tensor(value, getattr(message.privileged, name))
    return message


def encode_observation(obs: Observation, step: int) -> RobotState:
    """RobotState k as the sim publishes it after `step` steps: every field, the exact object
    pose as the estimate too, and the privileged block."""
    privileged = Privileged(obs.object_pose, obs.object_velocity, obs.physics_params)
    return encode(
        StateIn(
            0,
            step,
            obs.q,
            obs.dq,
            obs.episode_ids,
            obs.episode_step,
            tau=obs.tau,
            ee_pos_rot6d=obs.ee_pos_rot6d,
            goal_pose=obs.goal_pose,
            object_pose_estimate=obs.object_pose,
            privileged=privileged,
        )
    )
