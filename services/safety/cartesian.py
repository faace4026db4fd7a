"""Stage 3: Cartesian-space action clipping, the paper's Algorithm eq:cclip (lines 788-804).

Consumes the joint residual dq (B, J) and the end-effector Jacobian at the current
configuration (B, R, J), computed for the whole batch from the FR3's kinematic chain (read by
Pinocchio from the same model file as the sim, `hamnet.fr3.model`);
produces the clamped residual whose predicted end-effector motion ||J dq|| is at most eps_x,
up to what the damping lambda leaves (at most (lambda/2)*||dq|| per pass; see `cartesian_clip`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from hamnet.fr3.model import EE_SITE
from hamnet.safety.config import CartesianRows

JACOBIAN_ROWS: dict[str, slice] = {"linear": slice(0, 3), "full": slice(0, 6)}
"""Rows of the (6, J) world-aligned Jacobian [linear; angular] kept for Delta x."""


@dataclass(frozen=True)
class Chain:
    """The arm as a serial chain of revolute joints about their local z axes, as arrays, so
    that Jacobians are computed for a whole batch at once (no per-environment loop)."""

    rotations: np.ndarray
    """(J, 3, 3) placement of each joint frame in its parent joint's frame at q = 0."""
    translations: np.ndarray
    """(J, 3) the same placements' translations, m."""
    ee_translation: np.ndarray
    """(3,) the `ee` frame's origin in the last joint's frame, m."""


def chain_of(model: pin.Model) -> Chain:
    """The FR3's chain from its Pinocchio model (loaded from the sim's MJCF).

    Raises:
        ValueError: if a joint is not a revolute joint about z or the chain is not serial.
    """
    joints = range(1, model.njoints)
    kinds = {model.joints[j].shortname() for j in joints}
    if kinds != {"JointModelRZ"} or list(model.parents)[1:] != list(range(model.njoints - 1)):
        raise ValueError(f"expected a serial chain of RZ joints, got {kinds}")
    frame = model.frames[model.getFrameId(EE_SITE)]
    if frame.parentJoint != model.njoints - 1:
        raise ValueError(f"{EE_SITE} hangs from joint {frame.parentJoint}, not the last one")
    return Chain(
        rotations=np.array([model.jointPlacements[j].rotation for j in joints]),
        translations=np.array([model.jointPlacements[j].translation for j in joints]),
        ee_translation=np.array(frame.placement.translation),
    )


def ee_jacobians(chain: Chain, q: np.ndarray, rows: CartesianRows = "linear") -> np.ndarray:
    """Algorithm eq:cclip line 1, J = dx/dq at q, for every environment at once.

    Forward kinematics joint by joint over the batch; column j is [z_j x (p_ee - p_j); z_j]
    with z_j and p_j joint j's world axis and origin (Pinocchio's LOCAL_WORLD_ALIGNED frame
    Jacobian, the convention of `hamnet.fr3.model.mujoco_ee_jacobian`; tests check both).

    Args:
        chain: the arm (`chain_of`).
        q: (B, J) finite joint positions, rad.
        rows: "linear" (3 rows, m/rad) or "full" (6 rows: linear then angular).
    Returns:
        (B, R, J) Jacobians at the paddle's `ee` frame, world-aligned.
    """
    q = np.asarray(q, dtype=np.float64)  # (B, J)
    b, num_joints = q.shape
    # Rotations as (B*3, 3) stacks, so each product with a fixed (3, 3) is one 2-d matmul.
    rotation = np.tile(np.eye(3), (b, 1))  # (B*3, 3) world from the current frame
    position = np.zeros((b, 3))  # (B, 3), m
    axes, origins = np.empty((b, 3, num_joints)), np.empty((b, 3, num_joints))
    cos, sin = np.cos(q).repeat(3, axis=0), np.sin(q).repeat(3, axis=0)  # (B*3, J)
    for j in range(num_joints):
        position = position + (rotation @ chain.translations[j]).reshape(b, 3)
        rotation = rotation @ chain.rotations[j]
        axes[:, :, j], origins[:, :, j] = rotation[:, 2].reshape(b, 3), position
        x, y = rotation[:, 0], rotation[:, 1]  # (B*3,) columns; z is the axis
        c, s = cos[:, j], sin[:, j]
        rotation = np.stack([c * x + s * y, c * y - s * x, rotation[:, 2]], axis=1)
    ee = position + (rotation @ chain.ee_translation).reshape(b, 3)  # (B, 3)
    a0, a1, a2 = axes.transpose(1, 0, 2)  # (B, J) each
    d0, d1, d2 = (ee[:, :, None] - origins).transpose(1, 0, 2)  # joint origin to ee, (B, J)
    linear = np.stack([a1 * d2 - a2 * d1, a2 * d0 - a0 * d2, a0 * d1 - a1 * d0], axis=1)
    if rows == "linear":
        return linear  # (B, 3, J)
    return np.concatenate([linear, axes], axis=1)  # (B, 6, J)


def excess_motion(dx: np.ndarray, eps_x: float) -> np.ndarray:
    """Line 4: dx_excess = dx*(||dx|| - eps_x)/||dx|| where ||dx|| > eps_x, else 0; (B, R)."""
    norm = np.linalg.norm(dx, axis=1)  # (B,)
    over = norm > eps_x
    share = np.where(over, (norm - eps_x) / np.where(over, norm, 1.0), 0.0)  # (B,)
    return dx * share[:, None]


def damped_least_squares(jacobian: np.ndarray, dx: np.ndarray, damping: float) -> np.ndarray:
    """Line 5: J^T (J J^T + lambda^2 I)^-1 dx, batched; (B, J) from J (B, R, J), dx (B, R).

    With lambda = 0 the pseudo-inverse replaces the inverse, so a singular J stays defined."""
    rows = jacobian.shape[1]
    gram = jacobian @ jacobian.transpose(0, 2, 1) + damping**2 * np.eye(rows)  # (B, R, R)
    if damping > 0.0:
        y = np.linalg.solve(gram, dx[:, :, None])[:, :, 0]  # (B, R)
    else:
        y = np.einsum("brs,bs->br", np.linalg.pinv(gram), dx)
    return np.einsum("brj,br->bj", jacobian, y)


def cartesian_clip(
    dq: np.ndarray, jacobian: np.ndarray, eps_x: float, damping: float, iterations: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Algorithm eq:cclip: remove the end-effector motion beyond eps_x from the residual.

    In the singular-value basis of J each component of dq shrinks by c*s^2/(s^2 + lambda^2)
    with c = (||dx|| - eps_x)/||dx||, so ||dq_clamped|| <= ||dq|| and
    ||J dq_clamped|| <= eps_x + c*(lambda/2)*||dq||; a further pass (iterations > 1) applies
    the same algorithm to what is left.

    Args:
        dq: (B, J) joint residual, rad (line 2).
        jacobian: (B, R, J) Jacobian at the current configuration (line 1).
        eps_x: Cartesian bound per policy step (m for linear rows).
        damping: lambda.
        iterations: passes of lines 3-6 with the same J.
    Returns:
        dq_clamped (B, J) rad, and excess (B,): ||J dq|| - eps_x before clamping where
        positive, else 0 (m for linear rows).
    """
    excess = np.maximum(np.linalg.norm(np.einsum("brj,bj->br", jacobian, dq), axis=1) - eps_x, 0.0)
    for _ in range(iterations):
        dx = np.einsum("brj,bj->br", jacobian, dq)  # line 3, (B, R)
        dx_excess = excess_motion(dx, eps_x)  # line 4, (B, R)
        dq = dq - damped_least_squares(jacobian, dx_excess, damping)  # lines 5-6, (B, J)
    return dq, excess
