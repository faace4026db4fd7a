"""Stage 3: Cartesian-space action clipping, the paper's Algorithm eq:cclip (lines 788-804).

Consumes the joint residual dq (B, J) and the end-effector Jacobian at the current
configuration (B, R, J) from Pinocchio (the same FR3 model file as the sim, `hamnet.fr3.model`);
produces the clamped residual whose predicted end-effector motion ||J dq|| is at most eps_x,
up to what the damping lambda leaves (at most (lambda/2)*||dq|| per pass; see `cartesian_clip`).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hamnet.fr3.model import EE_SITE
from hamnet.safety.config import CartesianRows

JACOBIAN_ROWS: dict[str, slice] = {"linear": slice(0, 3), "full": slice(0, 6)}
"""Rows of the (6, J) world-aligned Jacobian [linear; angular] kept for Delta x."""


def ee_jacobians(
    model: pin.Model, data: pin.Data, q: np.ndarray, rows: CartesianRows = "linear"
) -> np.ndarray:
    """Algorithm eq:cclip line 1, J = dx/dq at q, for every environment (one pin.Data reused).

    Args:
        model, data: the FR3 from `hamnet.fr3.model.load_pinocchio()`; data is scratch.
        q: (B, J) finite joint positions, rad.
        rows: "linear" (3 rows, m/rad) or "full" (6 rows: linear then angular).
    Returns:
        (B, R, J) Jacobians at the paddle's `ee` frame, world-aligned (LOCAL_WORLD_ALIGNED,
        the convention of `hamnet.fr3.model.mujoco_ee_jacobian`).
    """
    frame = model.getFrameId(EE_SITE)
    keep = JACOBIAN_ROWS[rows]
    jacobians = np.empty((q.shape[0], keep.stop - keep.start, q.shape[1]))  # (B, R, J)
    for env, q_env in enumerate(np.asarray(q, dtype=np.float64)):
        full = pin.computeFrameJacobian(model, data, q_env, frame, pin.LOCAL_WORLD_ALIGNED)
        jacobians[env] = full[keep]  # (R, J)
    return jacobians


def excess_motion(dx: np.ndarray, eps_x: float) -> np.ndarray:
    """Line 4: dx_excess = dx*(||dx|| - eps_x)/||dx|| where ||dx|| > eps_x, else 0; (B, R)."""
    norm = np.linalg.norm(dx, axis=1)  # (B,)
    over = norm > eps_x
    share = np.where(over, (norm - eps_x) / np.where(over, norm, 1.0), 0.0)  # (B,)
    return dx * share[:, None]


def damped_least_squares(jacobian: np.ndarray, dx: np.ndarray, damping: float) -> np.ndarray:
    """Line 5: J^T (J J^T + lambda^2 I)^-1 dx, batched; (B, J) from J (B, R, J), dx (B, R),
    or (B, J, K) from K motions per environment dx (B, R, K), solved together.

    With lambda = 0 the pseudo-inverse replaces the inverse, so a singular J stays defined."""
    rows = jacobian.shape[1]
    gram = jacobian @ jacobian.transpose(0, 2, 1) + damping**2 * np.eye(rows)  # (B, R, R)
    columns = dx if dx.ndim == 3 else dx[:, :, None]  # (B, R, K)
    if damping > 0.0:
        y = np.linalg.solve(gram, columns)  # (B, R, K)
    else:
        y = np.linalg.pinv(gram) @ columns
    joints = jacobian.transpose(0, 2, 1) @ y  # (B, J, K)
    return joints if dx.ndim == 3 else joints[:, :, 0]


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
