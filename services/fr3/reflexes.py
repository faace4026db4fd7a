"""The reflex checks libfranka's FCI makes on commanded joint references, by name.

The FCI differentiates the commanded signal with backward differences at its control period and
stops the motion when a result leaves Franka's published limits (libfranka docs, "Motion stopped
due to discontinuities"). Checks, per tick k and joint, with dt the control period (1 ms) and the
limits of `hamnet.fr3.limits.FR3` (Franka's FR3 control-parameter table):

- `non_finite_command`: q_k or tau_k is NaN or infinite (libfranka rejects such a command
  with `std::invalid_argument` before it reaches the robot; here it is a reflex like the rest).
- `joint_motion_generator_position_limits_violation`: q_k outside [q_min, q_max].
- `joint_motion_generator_velocity_limits_violation`: |q_k - q_{k-1}| / dt > dq_max, which is
  also the discontinuity test "a jump in position larger than dq_max * dt".
- `joint_position_motion_generator_start_pose_invalid`: the same jump test on the first tick
  after start or recovery, against the measured start position.
- `joint_motion_generator_velocity_discontinuity`: second difference / dt^2 > ddq_max
  (the commanded velocity jumps by more than ddq_max * dt).
- `joint_motion_generator_acceleration_discontinuity`: third difference / dt^3 > jerk_max.
- `tau_j_range_violation`: |tau_k| > tau_max (only when torques are given).
- `controller_torque_discontinuity`: |tau_k - tau_{k-1}| / dt > dtau_max (torque rate).

The FR3's position-dependent velocity limits are not modelled: the constant dq_max of the
table is used. The bridge checks what it sends with these (`hamnet.bridge.core`), and its fake
robot refuses what they flag (`hamnet.bridge.fake_fr3`).
"""

from __future__ import annotations

import numpy as np

from hamnet.fr3.limits import FR3Limits

NON_FINITE = "non_finite_command"
"""A commanded value is NaN or infinite."""
POSITION_LIMITS = "joint_motion_generator_position_limits_violation"
"""Commanded position outside [q_min, q_max]."""
VELOCITY_LIMITS = "joint_motion_generator_velocity_limits_violation"
"""Backward-difference velocity above dq_max (a position jump above dq_max * dt)."""
START_POSE_INVALID = "joint_position_motion_generator_start_pose_invalid"
"""First command after (re)start jumps more than dq_max * dt from the measured position."""
VELOCITY_DISCONTINUITY = "joint_motion_generator_velocity_discontinuity"
"""Backward-difference acceleration above ddq_max."""
ACCELERATION_DISCONTINUITY = "joint_motion_generator_acceleration_discontinuity"
"""Backward-difference jerk above jerk_max."""
TORQUE_RANGE = "tau_j_range_violation"
"""Commanded torque above tau_max."""
TORQUE_DISCONTINUITY = "controller_torque_discontinuity"
"""Backward-difference torque rate above dtau_max."""

REFLEXES = (
    NON_FINITE,
    POSITION_LIMITS,
    VELOCITY_LIMITS,
    START_POSE_INVALID,
    VELOCITY_DISCONTINUITY,
    ACCELERATION_DISCONTINUITY,
    TORQUE_RANGE,
    TORQUE_DISCONTINUITY,
)
"""Every reflex checked, in the order of the last axis of `reflex_flags` (R = 8)."""


def backward_differences(q: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, acceleration and jerk of a sampled signal by backward differences.

    Args:
        q: three samples of history then S new ones, (B, 3 + S, J).
        dt: sample period, s.
    Returns:
        velocity, acceleration, jerk at the S new samples, (B, S, J) each, per s, s^2, s^3.
    """
    velocity = np.diff(q, axis=1) / dt  # (B, 2 + S, J)
    acceleration = np.diff(velocity, axis=1) / dt  # (B, 1 + S, J)
    jerk = np.diff(acceleration, axis=1) / dt  # (B, S, J)
    return velocity[:, 2:], acceleration[:, 1:], jerk


def reflex_flags(
    q: np.ndarray,
    tau: np.ndarray | None,
    limits: FR3Limits,
    dt: float,
    relative_tolerance: float = 0.0,
    start: np.ndarray | None = None,
) -> np.ndarray:
    """Which reflexes each new tick triggers (ticks after the first offending one included).

    Args:
        q: three commanded (or resting) positions of history then S new ones, (B, 3 + S, J), rad.
        tau: last commanded torque then S new ones, (B, 1 + S, J), N m; None when not given.
        limits: the robot's limits.
        dt: control period, s.
        relative_tolerance: allowed excess of differentiated quantities, fraction of the limit.
        start: robots whose first new tick is the first after (re)start, (B,) bool.
    Returns:
        (B, S, R) bool, R = len(REFLEXES), in REFLEXES order.
    """
    slack = 1.0 + relative_tolerance
    new = q[:, 3:]  # (B, S, J), rad
    velocity, acceleration, jerk = backward_differences(q, dt)  # (B, S, J) each
    over_speed = np.any(np.abs(velocity) > slack * limits.dq_max, axis=2)  # (B, S)
    first_tick = np.zeros_like(over_speed)  # (B, S)
    if start is not None:
        first_tick[:, 0] = start
    flags = {
        NON_FINITE: ~np.all(np.isfinite(new), axis=2),
        POSITION_LIMITS: np.any((new < limits.q_min) | (new > limits.q_max), axis=2),
        VELOCITY_LIMITS: over_speed,
        START_POSE_INVALID: over_speed & first_tick,
        VELOCITY_DISCONTINUITY: np.any(np.abs(acceleration) > slack * limits.ddq_max, axis=2),
        ACCELERATION_DISCONTINUITY: np.any(np.abs(jerk) > slack * limits.jerk_max, axis=2),
    }
    no_torque = np.zeros_like(over_speed)  # (B, S)
    flags[TORQUE_RANGE] = flags[TORQUE_DISCONTINUITY] = no_torque
    if tau is not None:
        rate = np.diff(tau, axis=1) / dt  # (B, S, J), N m/s
        flags[NON_FINITE] |= ~np.all(np.isfinite(tau[:, 1:]), axis=2)
        flags[TORQUE_RANGE] = np.any(np.abs(tau[:, 1:]) > limits.tau_max, axis=2)
        flags[TORQUE_DISCONTINUITY] = np.any(np.abs(rate) > slack * limits.dtau_max, axis=2)
    return np.stack([flags[name] for name in REFLEXES], axis=2)  # (B, S, R)
