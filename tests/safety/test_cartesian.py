"""Stage 3, Algorithm eq:cclip: hand-computed clamps on a known Jacobian, Pinocchio's
Jacobian against MuJoCo's, and the bound ||J dq_clamped|| <= eps_x (up to the damping's
tolerance) checked with MuJoCo's own Jacobian over random configurations and residuals."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hamnet.fr3 import limits as fr3_limits
from hamnet.fr3 import model as fr3_model
from hamnet.fr3.limits import FR3
from hamnet.safety.cartesian import cartesian_clip, damped_least_squares, ee_jacobians

B, J = 4, 7
PIN_MODEL, PIN_DATA = fr3_model.load_pinocchio()
MJ_MODEL = fr3_model.load_mujoco()
MJ_DATA = mujoco.MjData(MJ_MODEL)


def mujoco_jacobians(q: np.ndarray) -> np.ndarray:
    """(B, 6, J) MuJoCo Jacobians, the independent reference."""
    return np.stack([fr3_model.mujoco_ee_jacobian(MJ_MODEL, MJ_DATA, q_env) for q_env in q])


def selector_jacobian() -> np.ndarray:
    """(B, 3, J) J = [I_3 | 0]: dx is the first three joints' residual."""
    jacobian = np.zeros((B, 3, J))
    jacobian[:, :, :3] = np.eye(3)
    return jacobian


def test_clamp_by_hand_on_a_selector_jacobian() -> None:
    """dq = (0.3, 0.4, 0, ...): ||dx|| = 0.5 > 0.12, dx_excess = dx*(0.38/0.5); with J J^T = I
    the DLS step is dx_excess/(1 + lambda^2). Env 1 is under the bound, env 2 is zero, env 3
    moves only joints J does not see: all three unchanged."""
    dq = np.zeros((B, J))
    dq[0, :3] = [0.3, 0.4, 0.0]
    dq[0, 5] = 0.2
    dq[1, :3] = [0.06, 0.08, 0.0]
    dq[3, 3:] = 0.25
    clamped, excess = cartesian_clip(dq, selector_jacobian(), eps_x=0.12, damping=0.0)
    np.testing.assert_allclose(clamped[0], [0.072, 0.096, 0.0, 0.0, 0.0, 0.2, 0.0])
    np.testing.assert_array_equal(clamped[1:], dq[1:])
    np.testing.assert_allclose(excess, [0.38, 0.0, 0.0, 0.0])
    damped, _ = cartesian_clip(dq, selector_jacobian(), eps_x=0.12, damping=0.5)
    np.testing.assert_allclose(damped[0, :3], dq[0, :3] - dq[0, :3] * 0.76 / 1.25)


def test_dls_matches_the_formula_on_a_random_jacobian() -> None:
    rng = np.random.default_rng(0)
    jacobian, dx = rng.normal(size=(B, 3, J)), rng.normal(size=(B, 3))
    got = damped_least_squares(jacobian, dx, 0.1)
    for env in range(B):
        jac = jacobian[env]
        want = jac.T @ np.linalg.inv(jac @ jac.T + 0.01 * np.eye(3)) @ dx[env]
        np.testing.assert_allclose(got[env], want, rtol=1e-10, atol=1e-12)
    both = damped_least_squares(jacobian, np.stack([dx, -2.0 * dx], axis=2), 0.1)  # (B, J, 2)
    np.testing.assert_allclose(both, np.stack([got, -2.0 * got], axis=2), rtol=1e-10, atol=1e-12)


def test_zero_damping_survives_a_singular_jacobian() -> None:
    jacobian = np.zeros((B, 3, J))
    jacobian[:, 0, 0] = 1.0  # rank 1
    dq = np.full((B, J), 0.25)
    clamped, _ = cartesian_clip(dq, jacobian, eps_x=0.12, damping=0.0)
    assert np.all(np.isfinite(clamped)) and np.allclose(clamped[:, 0], 0.12)


configurations = arrays(
    np.float64, (B, J), elements=st.floats(0.0, 1.0)
).map(lambda u: FR3.q_min + u * (FR3.q_max - FR3.q_min))  # (B, J) anywhere in the FR3 box
residuals = arrays(np.float64, (B, J), elements=st.floats(-0.26, 0.26))  # stage 2's output


@settings(max_examples=25, deadline=None)
@given(q=configurations)
def test_pinocchio_jacobian_equals_mujocos(q: np.ndarray) -> None:
    pin_full = ee_jacobians(PIN_MODEL, PIN_DATA, q, rows="full")  # (B, 6, J)
    np.testing.assert_allclose(pin_full, mujoco_jacobians(q), atol=1e-9)
    np.testing.assert_array_equal(ee_jacobians(PIN_MODEL, PIN_DATA, q), pin_full[:, :3])


@settings(max_examples=40, deadline=None)
@given(
    q=configurations,
    dq=residuals,
    eps_x=st.sampled_from([0.12, 0.24, 0.01]),
    damping=st.sampled_from([0.0, 0.01, 0.1]),
)
def test_clamped_motion_is_within_eps_x_by_mujocos_jacobian(
    q: np.ndarray, dq: np.ndarray, eps_x: float, damping: float
) -> None:
    """||J dq_c|| <= eps_x + c*(lambda/2)*||dq|| with c = (||J dq|| - eps_x)/||J dq||, where J
    is MuJoCo's; the clamp never grows ||dq|| and leaves unclipped residuals alone."""
    jacobian = mujoco_jacobians(q)[:, :3]  # (B, 3, J), MuJoCo's
    clamped, excess = cartesian_clip(dq, ee_jacobians(PIN_MODEL, PIN_DATA, q), eps_x, damping)
    motion = np.linalg.norm(np.einsum("brj,bj->br", jacobian, dq), axis=1)  # (B,)
    clamped_motion = np.linalg.norm(np.einsum("brj,bj->br", jacobian, clamped), axis=1)
    share = np.where(motion > eps_x, (motion - eps_x) / np.maximum(motion, 1e-300), 0.0)
    tolerance = share * damping / 2 * np.linalg.norm(dq, axis=1) + 1e-9
    assert np.all(clamped_motion <= eps_x + tolerance)
    assert np.all(np.linalg.norm(clamped, axis=1) <= np.linalg.norm(dq, axis=1) + 1e-12)
    under = motion <= eps_x
    np.testing.assert_array_equal(clamped[under], dq[under])
    np.testing.assert_allclose(excess, np.maximum(motion - eps_x, 0.0), atol=1e-9)


@settings(max_examples=20, deadline=None)
@given(q=configurations, dq=residuals)
def test_more_passes_close_the_damping_gap(q: np.ndarray, dq: np.ndarray) -> None:
    """With lambda = 0.05 one pass may leave some excess; five passes leave less, and a
    negligible lambda lands on eps_x itself wherever the residual was clipped."""
    jacobian = ee_jacobians(PIN_MODEL, PIN_DATA, q)

    def motion(x: np.ndarray) -> np.ndarray:
        return np.linalg.norm(np.einsum("brj,bj->br", jacobian, x), axis=1)

    one, _ = cartesian_clip(dq, jacobian, 0.12, 0.05, iterations=1)
    five, _ = cartesian_clip(dq, jacobian, 0.12, 0.05, iterations=5)
    assert np.all(motion(five) <= np.maximum(motion(one), 0.12) + 1e-12)
    exact, _ = cartesian_clip(dq, jacobian, 0.12, 1e-9)
    clipped = motion(dq) > 0.12
    np.testing.assert_allclose(motion(exact)[clipped], 0.12, rtol=1e-6)


def test_home_pose_clamp_is_a_small_change() -> None:
    """At home a 0.26 rad push of joints 1-4 moves the paddle ~0.3 m; clamped to 0.12 m."""
    q = np.tile(fr3_limits.Q_HOME, (B, 1))
    dq = np.zeros((B, J))
    dq[:, :4] = [0.26, 0.26, 0.26, -0.26]
    clamped, excess = cartesian_clip(dq, ee_jacobians(PIN_MODEL, PIN_DATA, q), 0.12, 0.01)
    jacobian = mujoco_jacobians(q)[:, :3]
    assert np.all(excess > 0.05)
    np.testing.assert_allclose(
        np.linalg.norm(np.einsum("brj,bj->br", jacobian, clamped), axis=1), 0.12, rtol=1e-3
    )
    assert pytest.approx(0.0, abs=1e-12) == np.ptp(clamped, axis=0).max()  # same per env
