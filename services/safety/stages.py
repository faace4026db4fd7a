"""The safety stages 1, 2, 4, 5 and 7 as small pure functions, batched over B environments.

Each takes arrays and returns the new values plus `excess` (B,): how much it removed, in the
stage's unit (see `stats`). Stage 3 (Cartesian clipping) lives in `cartesian`, stage 6
(trajectory generation) in `trajectory`; `pipeline` chains them and keeps the per-env state.

Raw action layout (B, 21) = [dq | kp | rho], 7 columns each in joint order. A raw component a
becomes u = squash(a) in [-1, 1] (`ActionMagnitudeConfig.squash`), then
    dq  = xi*u                       ("scale", default) or clip(xi_max*u, -xi, xi) ("clip")
    dq  = clip(DLS(J, s*u[:6]), -xi, xi)   in "paddle" space: u[:6] the paddle's twist
    kp  = kp_min + (u+1)/2*(kp_max - kp_min)       in [10, 200] N m/rad
    rho = rho_min + (u+1)/2*(rho_max - rho_min)    in [0.3, 2.0]
    kd  = rho*sqrt(kp)                              (paper line 241)
Legend: B environments, J = 7 joints, S control samples.
"""

from __future__ import annotations

from collections.abc import Callable
from enum import IntEnum

import numpy as np

from hamnet.fr3.limits import ACTION_DIM, FR3, NUM_JOINTS
from hamnet.safety.cartesian import damped_least_squares
from hamnet.safety.config import ActionMagnitudeConfig


class Rejection(IntEnum):
    """Why an environment's action was rejected (0: accepted). Values 1-2 equal the proto's
    SafetyEventKind REJECTED_NONFINITE / REJECTED_SHAPE."""

    ACCEPTED = 0
    NONFINITE = 1
    """The action holds NaN or Inf."""
    SHAPE = 2
    """The action is not a (B, 21) array of real numbers (rejects every environment)."""
    STATE = 3
    """The robot state (q or dq) holds NaN or Inf: no residual can be applied to it."""
    EPISODE = 4
    """The action was computed for another episode than the state's: a residual meant for
    the old scene would move the arm of the new one."""


# --- stage 1 ----------------------------------------------------------------------------


def nonfinite_guard(action: object, num_envs: int) -> tuple[np.ndarray, np.ndarray]:
    """Stage 1: reject wrongly shaped or non-finite actions.

    Args:
        action: the policy's raw action, expected (B, 21) real numbers; anything else is
            rejected for every environment.
        num_envs: B.
    Returns:
        action (B, 21) float64 with rejected rows zeroed (so later stages stay finite), and
        reason (B,) int8 `Rejection` codes.
    """
    reason = np.zeros(num_envs, dtype=np.int8)  # (B,)
    zeros = np.zeros((num_envs, ACTION_DIM))  # (B, 21)
    try:
        array = np.asarray(action)
    except (TypeError, ValueError):  # ragged nested sequences
        array = None
    if array is None or array.dtype.kind not in "biuf" or array.shape != (num_envs, ACTION_DIM):
        reason[:] = Rejection.SHAPE
        return zeros, reason
    array = array.astype(np.float64)  # (B, 21)
    finite = np.isfinite(array).all(axis=1)  # (B,)
    reason[~finite] = Rejection.NONFINITE
    return np.where(finite[:, None], array, 0.0), reason


# --- stage 2 ----------------------------------------------------------------------------

SQUASHES: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "clip": lambda raw: np.clip(raw, -1.0, 1.0),
    "tanh": np.tanh,
}
"""Raw action component -> u in [-1, 1], by `ActionMagnitudeConfig.squash`."""


def _unsquashed(raw: np.ndarray, squash: str) -> np.ndarray:
    """What u would be without saturation: raw itself for "clip", tanh(raw) for "tanh"."""
    return raw if squash == "clip" else np.tanh(raw)


def affine_range(u: np.ndarray, low: float, high: float) -> np.ndarray:
    """u in [-1, 1] mapped linearly onto [low, high]."""
    return low + 0.5 * (u + 1.0) * (high - low)


def twist_scale(config: ActionMagnitudeConfig) -> np.ndarray:
    """(6,) the paddle twist at u = 1 in "paddle" space: [linear m | angular rad] per step."""
    return np.repeat([config.twist_linear, config.twist_angular], 3)


def action_magnitude(
    action: np.ndarray,
    xi: np.ndarray,
    config: ActionMagnitudeConfig,
    jacobian: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stage 2: raw action to joint residual, stiffness and damping ratio, dq bounded by xi.

    Args:
        action: (B, 21) finite raw action [dq | kp | rho].
        xi: (J,) action-magnitude bound per joint for this step, rad (`schedule.xi_at`).
        config: ranges, squash, mode and action space.
        jacobian: (B, 6, J) the paddle's world-aligned Jacobians at the measured postures
            (`cartesian.ee_jacobians(..., "full")`); needed in "paddle" space only.
    Returns:
        dq (B, J) rad with |dq| <= xi, kp (B, J) N m/rad, rho (B, J), and excess (B,): the
        largest |dq_nominal - dq| over the joints, rad, where dq_nominal reads the raw
        residual linearly (s*raw for "clip" squash, s*tanh(raw) for "tanh"; s = xi in
        "scale" mode, xi_max in "clip" mode; in "paddle" space the joint motion of the
        unsquashed twist).
    """
    u = SQUASHES[config.squash](action)  # (B, 21) in [-1, 1]
    raw_dq, u_dq = action[:, :NUM_JOINTS], u[:, :NUM_JOINTS]  # (B, J)
    if config.space == "paddle":
        if jacobian is None:
            raise ValueError("the paddle action space needs the paddle's Jacobians")
        twists = np.stack([_unsquashed(raw_dq[:, :6], config.squash), u_dq[:, :6]], axis=2)
        scale = twist_scale(config)[:, None]  # (6, 1)
        joints = damped_least_squares(jacobian, twists * scale, config.twist_damping)  # (B, J, 2)
        nominal, dq = joints[:, :, 0], np.clip(joints[:, :, 1], -xi, xi)
    elif config.mode == "scale":
        dq = xi * u_dq  # (B, J)
        nominal = xi * _unsquashed(raw_dq, config.squash)
    else:
        xi_max = np.full(NUM_JOINTS, config.xi_max_small)  # (J,)
        xi_max[: config.num_large_joints] = config.xi_max_large
        dq = np.clip(xi_max * u_dq, -xi, xi)
        nominal = xi_max * _unsquashed(raw_dq, config.squash)
    kp = affine_range(u[:, NUM_JOINTS : 2 * NUM_JOINTS], config.kp_min, config.kp_max)  # (B, J)
    rho = affine_range(u[:, 2 * NUM_JOINTS :], config.rho_min, config.rho_max)  # (B, J)
    return dq, kp, rho, np.abs(nominal - dq).max(axis=1)


# --- stage 4 ----------------------------------------------------------------------------


def residual_smoothing(
    dq: np.ndarray, dq_smoothed: np.ndarray, alpha: float
) -> tuple[np.ndarray, np.ndarray]:
    """Stage 4: dq_bar_t = alpha*dq_t + (1 - alpha)*dq_bar_{t-1} (paper line 808).

    Args:
        dq: (B, J) residual of this step, rad.
        dq_smoothed: (B, J) dq_bar_{t-1}, zero at an episode's start.
        alpha: weight of the newest residual.
    Returns:
        dq_bar (B, J) rad, and excess (B,): largest |dq - dq_bar| over the joints, rad.
    """
    dq_bar = alpha * dq + (1.0 - alpha) * dq_smoothed  # (B, J)
    return dq_bar, np.abs(dq - dq_bar).max(axis=1)


# --- stage 5 ----------------------------------------------------------------------------


def joint_target_bounds(
    central_fraction: float, q_min: np.ndarray = FR3.q_min, q_max: np.ndarray = FR3.q_max
) -> tuple[np.ndarray, np.ndarray]:
    """The central `central_fraction` of each joint range: (lo, hi), each (J,), rad."""
    middle, half = 0.5 * (q_min + q_max), 0.5 * central_fraction * (q_max - q_min)  # (J,)
    return middle - half, middle + half


def joint_limits(
    q_target: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Stage 5: the joint target q + dq_bar clipped into [lo, hi].

    Args:
        q_target: (B, J) wanted joint target, rad.
        lo, hi: (J,) bounds from `joint_target_bounds`.
    Returns:
        q_target (B, J) inside the bounds, and excess (B,): largest removed part, rad.
    """
    clipped = np.clip(q_target, lo, hi)  # (B, J)
    return clipped, np.abs(q_target - clipped).max(axis=1)


# --- stage 7 ----------------------------------------------------------------------------


def damping_gain(kp: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """kd = rho*sqrt(kp) (paper line 241), N m s/rad."""
    return rho * np.sqrt(kp)


def reference_error(q_ref: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Largest |q_ref - q| over the period: (B, J) from q_ref (B, J) or samples (B, S, J)."""
    with np.errstate(over="ignore"):  # opposite huge values: inf, handled by the callers
        if q_ref.ndim == 3:
            return np.abs(q_ref - q[:, None, :]).max(axis=1)  # (B, J)
        return np.abs(q_ref - q)


def impedance_terms(
    q_ref: np.ndarray, q: np.ndarray, dq: np.ndarray, kp: np.ndarray, kd: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Spring and damper torque bounds kp*|q_ref - q| and kd*|qdot|, each (B, J), N m.

    A zero gain gives zero torque even against an infinite error (not 0*inf = NaN); huge
    finite values may overflow to inf, which the caller treats as "over any limit"."""
    with np.errstate(over="ignore", invalid="ignore"):
        spring = np.where(kp > 0.0, kp * reference_error(q_ref, q), 0.0)
        damper = np.where(kd > 0.0, kd * np.abs(dq), 0.0)
    return spring, damper


def predicted_torque(
    q_ref: np.ndarray, q: np.ndarray, dq: np.ndarray, kp: np.ndarray, kd: np.ndarray
) -> np.ndarray:
    """Bound on the impedance torque: kp*|q_ref - q| + kd*|qdot|, (B, J), N m."""
    spring, damper = impedance_terms(q_ref, q, dq, kp, kd)
    with np.errstate(over="ignore"):
        return spring + damper


def torque_preclip(
    q_ref: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    kp: np.ndarray,
    rho: np.ndarray,
    tau_limit: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stage 7: scale kp by s (kd by sqrt(s), rho kept) where the predicted torque exceeds
    tau_limit, so that s*kp*e + sqrt(s)*kd*v = tau_limit.

    With w = sqrt(s) the condition is kp*e*w^2 + kd*v*w - tau_limit = 0, whose positive root
    in the cancellation-free form is w = 2*tau_limit / (kd*v + sqrt((kd*v)^2 + 4*kp*e*tau_limit)).

    Args:
        q_ref: (B, J) joint target or (B, S, J) sampled reference, rad.
        q, dq: (B, J) finite joint positions (rad) and velocities (rad/s).
        kp: (B, J) stiffness, N m/rad; rho: (B, J) damping ratio.
        tau_limit: (J,) or (B, J) torque bound, N m.
    Returns:
        kp, kd (B, J) with predicted_torque <= tau_limit, and excess (B,): largest predicted
        torque above tau_limit before the reduction, N m.
    """
    kd = damping_gain(kp, rho)  # (B, J)
    spring, damper = impedance_terms(q_ref, q, dq, kp, kd)  # (B, J), N m
    # An infinite term gives w = 0; joints under the limit may divide 0 by 0 in the branch
    # np.where discards.
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        torque = spring + damper
        over = torque > tau_limit  # (B, J)
        root = np.sqrt(damper**2 + 4.0 * spring * tau_limit)
        # The shave keeps the reduced torque under the limit despite rounding.
        w = np.where(over, 2.0 * tau_limit / (damper + root) * (1.0 - 1e-9), 1.0)
    return kp * w**2, kd * w, np.maximum(torque - tau_limit, 0.0).max(axis=1)
