"""SafeCommand (safety -> sim, bridge): the joint references and gains an executor applies
for one policy period, encoded from the safety filter's output and decoded into `Command`.

`hold_command` is the one Command made without the filter: holding the arm where it is (the
sim before its first SafeCommand, the bridge's check, benchmarks and tests that stand in for
the safety filter).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from hamnet.fr3.limits import FR3, NUM_JOINTS
from hamnet.proto.common_pb2 import Header
from hamnet.proto.safety_pb2 import CommandMode, SafeCommand
from hamnet.runtime.tensor import PayloadError, field_array, from_tensor, to_tensor


class References(Protocol):
    """What a SafeCommand is encoded from (`hamnet.safety.filter.SafeOutput`)."""

    q_ref: np.ndarray  # (B, S, J) rad
    dq_ref: np.ndarray  # (B, S, J) rad/s
    kp: np.ndarray  # (B, J) N m/rad
    kd: np.ndarray  # (B, J) N m s/rad
    tau_limit: np.ndarray  # (B, J) N m


@dataclass(frozen=True)
class Command:
    """What the safety filter sends for one policy period (the SafeCommand message)."""

    q_ref: np.ndarray
    """(B, S, J) joint references, one per control sample, rad."""
    kp: np.ndarray
    """(B, J) stiffness, N m/rad."""
    kd: np.ndarray
    """(B, J) damping, N m s/rad."""
    tau_limit: np.ndarray
    """(B, J) torque clip, N m."""
    episode_ids: np.ndarray | None = None
    """(B,) int64 episodes of the state the command answers (None: not sent)."""


HOLD_KP = 100.0
"""Stiffness of a hold, N m/rad: the middle of the impedance range kp in [10, 200]."""
HOLD_RHO = 1.0
"""Damping ratio of a hold (critically damped-ish): kd = rho*sqrt(kp), N m s/rad."""


def hold_command(
    q: np.ndarray, control_samples: int, kp: float = HOLD_KP, rho: float = HOLD_RHO
) -> Command:
    """Track the joint positions `q` for one policy period.

    Args:
        q: (B, J) joint positions to hold, rad.
        control_samples: S, reference samples per policy period.
        kp: stiffness, N m/rad; rho: damping ratio.
    Returns:
        A Command with q_ref (B, S, J) = q, kp, kd (B, J) and tau_limit (B, J) = FR3.tau_max.
    """
    q = np.asarray(q, dtype=np.float64)  # (B, J)
    b, j = q.shape
    return Command(
        q_ref=np.repeat(q[:, None, :], control_samples, axis=1),  # (B, S, J)
        kp=np.full((b, j), kp),
        kd=np.full((b, j), rho * np.sqrt(kp)),
        tau_limit=np.tile(FR3.tau_max, (b, 1)),
    )


def decode(
    message: SafeCommand, num_envs: int, control_samples: int, control_dt: float
) -> tuple[int, Command]:
    """The step a SafeCommand answers and the Command to apply.

    Args:
        message: the parsed SafeCommand.
        num_envs: B; control_samples: S; control_dt: the executor's sample period, s.
    Returns:
        (header.step, Command with q_ref (B, S, J), kp, kd, tau_limit (B, J) and the
        episode ids (B,) if sent).
    Raises:
        PayloadError: `missing`, `dtype`, `shape` (batch size, sample count or joint count
            differ from the executor's), `nonfinite`, `range` (negative gain or torque
            limit), or `control_dt` (a sample period other than the executor's).
    """
    b, s, j = num_envs, control_samples, NUM_JOINTS
    q_ref = field_array(message, "q_ref", None, (b, s, j))
    gains = {name: field_array(message, name, None, (b, j)) for name in ("kp", "kd", "tau_limit")}
    if message.HasField("dq_ref"):  # checked, unused: the impedance law damps towards rest
        field_array(message, "dq_ref", None, (b, s, j))
    episode_ids = None
    if message.HasField("episode_ids"):
        episode_ids = from_tensor(message.episode_ids, np.int64, (b,))
    negative = [name for name, value in gains.items() if (value < 0).any()]
    if negative:
        raise PayloadError("range", f"SafeCommand.{', '.join(negative)} must be >= 0")
    if message.control_dt and abs(message.control_dt - control_dt) > 1e-9:
        raise PayloadError(
            "control_dt", f"samples of {message.control_dt} s, the sim's are {control_dt} s"
        )
    return message.header.step, Command(q_ref=q_ref, episode_ids=episode_ids, **gains)


def encode(
    references: References,
    step: int,
    mode: CommandMode.ValueType,
    episode_ids: np.ndarray,
    control_dt: float,
) -> SafeCommand:
    """SafeCommand k: references (B, S, J) and gains (B, J) in float64, the episodes (B,) of
    the state it answers, its mode and the sample period control_dt, s."""
    message = SafeCommand(header=Header(step=step), mode=mode, control_dt=control_dt)
    to_tensor(np.asarray(episode_ids, dtype=np.int64), message.episode_ids)
    for name in ("q_ref", "dq_ref", "kp", "kd", "tau_limit"):
        to_tensor(np.asarray(getattr(references, name), dtype=np.float64), getattr(message, name))
    return message
