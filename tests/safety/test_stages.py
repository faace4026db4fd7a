"""Safety stages 1, 2, 4, 5 and 7, the annealing schedule and the statistics: hand-computed
values at B = 4, plus hypothesis properties of the torque pre-clip over adversarial inputs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hamnet.fr3.limits import FR3
from hamnet.safety import stages
from hamnet.safety.config import (
    ActionMagnitudeConfig,
    AnnealingConfig,
    CartesianClipConfig,
    JointLimitsConfig,
    ResidualSmoothingConfig,
    SafetyConfig,
    TorquePreclipConfig,
)
from hamnet.safety.schedule import (
    SCHEDULE_NAMES,
    annealing_exponent,
    eps_x_at,
    per_joint,
    schedule_values,
    xi_at,
)
from hamnet.safety.stages import Rejection
from hamnet.safety.stats import (
    STAGE_NAMES,
    StageStats,
    StatsAccumulator,
    merge,
    stage_report,
    summarize,
)

B, J = 4, 7
NAN, INF = float("nan"), float("inf")
XI_STEP0 = per_joint(0.26, 0.21, 4)  # (J,) xi at step 0: xi_max per group


# --- stage 1 ----------------------------------------------------------------------------


def test_guard_rejects_nonfinite_rows_only() -> None:
    action = np.zeros((B, 21))
    action[1, 5] = NAN
    action[2, 20] = -INF
    action[3, 0] = 1e308  # huge but finite: stage 2 bounds it
    cleaned, reason = stages.nonfinite_guard(action, B)
    assert reason.tolist() == [0, Rejection.NONFINITE, Rejection.NONFINITE, 0]
    assert np.all(cleaned[1:3] == 0.0) and cleaned[3, 0] == 1e308
    assert cleaned.dtype == np.float64 and cleaned.shape == (B, 21)


@pytest.mark.parametrize(
    "action",
    [
        np.zeros((B, 20)),
        np.zeros((B + 1, 21)),
        np.zeros(21),
        np.zeros((B, 21), dtype=complex),
        np.array([["a"] * 21] * B),
        [[0.0] * 21, [0.0] * 20],
        None,
        "not an action",
    ],
    ids=["width", "batch", "flat", "complex", "strings", "ragged", "none", "text"],
)
def test_guard_rejects_every_env_for_a_wrong_shape_or_type(action: object) -> None:
    cleaned, reason = stages.nonfinite_guard(action, B)
    assert np.all(reason == Rejection.SHAPE)
    assert cleaned.shape == (B, 21) and np.all(cleaned == 0.0)


def test_guard_accepts_integer_actions() -> None:
    cleaned, reason = stages.nonfinite_guard(np.ones((B, 21), dtype=np.int32), B)
    assert np.all(reason == 0) and np.all(cleaned == 1.0) and cleaned.dtype == np.float64


# --- stage 2 ----------------------------------------------------------------------------


def test_action_magnitude_by_hand_at_xi_max() -> None:
    """u = clip(a): dq = xi*u with xi = 0.26 (joints 1-4) / 0.21 (5-7); kp = 10 + (u+1)/2*190;
    rho = 0.3 + (u+1)/2*1.7. Row 0 saturates joint 4 (a = 2): 0.26 removed."""
    action = np.zeros((B, 21))
    action[0, :7] = [1.0, -1.0, 0.5, 2.0, 0.0, -0.5, 1.0]
    action[1, 7:14] = [-1.0, 1.0, 0.0, -3.0, 0.5, 0.0, 0.0]
    action[2, 14:] = [-1.0, 1.0, 0.0, 5.0, -0.5, 0.0, 0.0]
    dq, kp, rho, excess = stages.action_magnitude(action, XI_STEP0, ActionMagnitudeConfig())
    np.testing.assert_allclose(dq[0], [0.26, -0.26, 0.13, 0.26, 0.0, -0.105, 0.21])
    np.testing.assert_allclose(kp[1], [10.0, 200.0, 105.0, 10.0, 152.5, 105.0, 105.0])
    np.testing.assert_allclose(rho[2], [0.3, 2.0, 1.15, 2.0, 0.725, 1.15, 1.15])
    np.testing.assert_allclose(excess, [0.26, 0.0, 0.0, 0.0])


def test_action_magnitude_clip_mode_and_tanh_squash() -> None:
    """Clip mode at xi = (0.16, 0.08): dq = clip(xi_max*u, -xi, xi); 0.5 -> 0.13 (large) kept,
    1 -> 0.26 cut to 0.16 (0.10 removed). tanh squash: dq = xi*tanh(a), nothing removed."""
    action = np.zeros((B, 21))
    action[0, :7] = [0.5, 1.0, -1.0, 0.0, 0.5, 0.2, -1.0]
    xi = per_joint(0.16, 0.08, 4)
    clip_mode = ActionMagnitudeConfig(mode="clip")
    dq, _, _, excess = stages.action_magnitude(action, xi, clip_mode)
    np.testing.assert_allclose(dq[0], [0.13, 0.16, -0.16, 0.0, 0.08, 0.042, -0.08])
    assert excess[0] == pytest.approx(0.21 - 0.08)  # joint 7: 0.21 asked, 0.08 allowed
    tanh = ActionMagnitudeConfig(squash="tanh")
    dq, kp, _, excess = stages.action_magnitude(action * 100, XI_STEP0, tanh)
    np.testing.assert_allclose(dq, XI_STEP0 * np.tanh(action[:, :7] * 100))
    assert np.all(excess == 0.0) and np.all((kp >= 10.0) & (kp <= 200.0))


def test_action_magnitude_bounds_huge_raw_values() -> None:
    action = np.full((B, 21), 1e308)
    action[1] = -1e308
    dq, kp, rho, excess = stages.action_magnitude(action, XI_STEP0, ActionMagnitudeConfig())
    np.testing.assert_allclose(np.abs(dq), np.tile(XI_STEP0, (B, 1)))
    assert np.all(np.isfinite(excess)) and np.all(excess > 1e300)
    assert kp[0, 0] == 200.0 and kp[1, 0] == 10.0 and rho[0, 0] == 2.0 and rho[1, 0] == 0.3


def test_paddle_space_asks_the_twist_through_the_jacobian() -> None:
    """ "paddle" space on a Jacobian with a known pseudo-inverse (the first six joints move
    the six twist axes, scaled by 2, the seventh nothing): dq = twist/2 up to the damping,
    the 7th raw component ignored, and a twist whose joint motion passes xi clipped to it
    (the cut reported as excess)."""
    config = ActionMagnitudeConfig(space="paddle", twist_damping=1e-6)
    jacobian = np.zeros((B, 6, J))
    jacobian[:, np.arange(6), np.arange(6)] = 2.0
    action = np.zeros((B, 21))
    action[0, :7] = [0.5, -1.0, 0.0, 1.0, 0.0, -0.5, 9.0]
    action[1, :6] = [40.0, 0, 0, 0, 0, 0]  # 1.2 m asked: 0.03 m kept, 0.6 rad cut to xi
    xi = per_joint(2.0, 2.0, 4)
    dq, kp, _, excess = stages.action_magnitude(action, xi, config, jacobian)
    np.testing.assert_allclose(dq[0], [0.0075, -0.015, 0.0, 0.05, 0.0, -0.025, 0.0], atol=1e-9)
    np.testing.assert_allclose(dq[1], [0.015, 0, 0, 0, 0, 0, 0], atol=1e-9)
    assert excess[1] == pytest.approx(0.6 - 0.015) and excess[0] == pytest.approx(0.0, abs=1e-9)
    small = per_joint(0.01, 0.01, 4)
    dq, _, _, excess = stages.action_magnitude(action, small, config, jacobian)
    assert np.abs(dq).max() <= 0.01 and excess[0] == pytest.approx(0.05 - 0.01)
    np.testing.assert_allclose(kp, np.full((B, J), 105.0))
    with pytest.raises(ValueError, match="Jacobians"):
        stages.action_magnitude(action, xi, config)


# --- schedule ---------------------------------------------------------------------------


def test_xi_anneals_geometrically_by_hand() -> None:
    """N_s = 1024, N_t = 2e6 vectorized steps of V = 1024 environments, counted in
    env_transitions: after k intervals xi = xi_max*(xi*/xi_max)^(1024k/2e6)."""
    config, v = ActionMagnitudeConfig(), 1024
    assert xi_at(0, config) == (0.26, 0.21)
    assert xi_at(1024 * v - 1, config) == (0.26, 0.21)  # the first update comes after N_s
    ratio_large = (0.16 / 0.26) ** (1024 / 2e6)
    assert xi_at(1024 * v, config)[0] == pytest.approx(0.26 * ratio_large)
    assert xi_at((10 * 1024 + 5) * v, config)[0] == pytest.approx(0.26 * ratio_large**10)
    small = 0.21 * (0.08 / 0.21) ** (976 * 1024 / 2e6)  # 1_000_000 // 1024 = 976 intervals
    assert xi_at(1_000_000 * v, config)[1] == pytest.approx(small)
    # N_t is not a multiple of N_s: at N_t, 1953 intervals give exponent 0.99994; the
    # 1954th interval (vectorized step 2_000_896) reaches xi* exactly, and it stays there.
    assert xi_at(2_000_000 * v, config) == pytest.approx((0.16, 0.08), rel=1e-4)
    for steps in (2_000_896 * v, 10**15):
        assert xi_at(steps, config) == pytest.approx((0.16, 0.08), rel=1e-12)


def test_schedule_holds_before_its_start_and_is_monotone() -> None:
    annealing = AnnealingConfig(start_step=5_000, interval=100, num_steps=1_000)
    config = CartesianClipConfig(annealing=annealing)
    assert eps_x_at(0, config) == eps_x_at(5_099, config) == 0.24
    assert eps_x_at(5_500, config) == pytest.approx(0.24 * 0.5**0.5)
    assert eps_x_at(6_000, config) == pytest.approx(0.12)
    values = [eps_x_at(step, config) for step in range(0, 8_000, 37)]
    assert all(a >= b for a, b in zip(values, values[1:]))
    assert annealing_exponent(-10, annealing) == 0.0


def test_disabled_magnitude_keeps_xi_max_and_names_are_stable() -> None:
    off = ActionMagnitudeConfig(enabled=False)
    assert xi_at(10**9, off) == (0.26, 0.21)
    values = schedule_values(0, ActionMagnitudeConfig(), CartesianClipConfig())
    assert SCHEDULE_NAMES == ("xi_large", "xi_small", "eps_x")
    assert values.as_dict() == {"xi_large": 0.26, "xi_small": 0.21, "eps_x": 0.24}


# --- stage 4 ----------------------------------------------------------------------------


def test_residual_smoothing_by_hand() -> None:
    """0.8*0.1 + 0.2*0.05 = 0.09; from zero memory the first value is 0.8*dq."""
    dq = np.full((B, J), 0.1)
    memory = np.zeros((B, J))
    memory[0] = 0.05
    dq_bar, excess = stages.residual_smoothing(dq, memory, 0.8)
    np.testing.assert_allclose(dq_bar[0], 0.09)
    np.testing.assert_allclose(dq_bar[1:], 0.08)
    np.testing.assert_allclose(excess, [0.01, 0.02, 0.02, 0.02])


# --- stage 5 ----------------------------------------------------------------------------


def test_joint_bounds_are_the_central_ninety_percent() -> None:
    """Joint 4: [-3.0770, -0.1169], range 2.9601, 5% = 0.148005 each side."""
    lo, hi = stages.joint_target_bounds(0.9)
    assert lo[3] == pytest.approx(-3.0770 + 0.148005)
    assert hi[3] == pytest.approx(-0.1169 - 0.148005)
    np.testing.assert_allclose(hi[[0, 2]], 0.9 * 2.9007)
    np.testing.assert_allclose(hi - lo, 0.9 * (FR3.q_max - FR3.q_min))


def test_joint_limits_clip_by_hand() -> None:
    lo, hi = stages.joint_target_bounds(0.9)
    wanted = np.tile((lo + hi) / 2, (B, 1))
    wanted[0, 0] = 3.0  # 3.0 - 2.61063 removed
    wanted[1, 3] = -3.2  # below -2.928995
    q_target, excess = stages.joint_limits(wanted, lo, hi)
    assert q_target[0, 0] == pytest.approx(2.61063) and q_target[1, 3] == pytest.approx(-2.928995)
    np.testing.assert_allclose(excess, [3.0 - 2.61063, 3.2 - 2.928995, 0.0, 0.0])


# --- stage 7 ----------------------------------------------------------------------------


def test_torque_preclip_by_hand() -> None:
    """Joint 5 (limit 10.8 N m): kp 100, rho 1 (kd 10), error 0.5, speed 1: 60 N m predicted.
    50 w^2 + 10 w = 10.8 gives w = (-10 + sqrt(2260))/100, kp = 100 w^2, kd = 10 w.
    Env 1: error 0 and speed 2 gives w = 10.8/20. Env 2 stays (1 N m). Env 3: a large joint."""
    limit = 0.9 * FR3.tau_max
    q = np.zeros((B, J))
    q_ref, dq = q.copy(), q.copy()
    kp, rho = np.full((B, J), 100.0), np.full((B, J), 1.0)
    q_ref[0, 4], dq[0, 4] = 0.5, 1.0
    dq[1, 4] = -2.0
    q_ref[2, 4] = 0.01
    q_ref[3, 0], dq[3, 0] = 1.0, 0.0
    kp_out, kd_out, excess = stages.torque_preclip(q_ref, q, dq, kp, rho, limit)
    w = (-10.0 + np.sqrt(2260.0)) / 100.0
    assert kp_out[0, 4] == pytest.approx(100 * w**2) and kd_out[0, 4] == pytest.approx(10 * w)
    assert kp_out[1, 4] == pytest.approx(100 * 0.54**2) and kd_out[1, 4] == pytest.approx(5.4)
    assert kp_out[2, 4] == 100.0 and kd_out[2, 4] == 10.0
    assert kp_out[3, 0] == pytest.approx(78.3)  # 100*1.0 > 78.3 N m: kp = 78.3
    np.testing.assert_allclose(excess, [60 - 10.8, 20 - 10.8, 0.0, 100 - 78.3])
    np.testing.assert_allclose(kd_out, stages.damping_gain(kp_out, rho))  # rho kept


def test_torque_preclip_uses_the_worst_reference_sample() -> None:
    q = np.zeros((B, J))
    samples = np.zeros((B, 3, J))
    samples[0, 1, 4] = 0.5  # overshoot mid-period, back at 0 at the end
    kp, kd, excess = stages.torque_preclip(samples, q, q, np.full((B, J), 100.0), 1.0, 10.8)
    assert kp[0, 4] == pytest.approx(10.8 / 0.5) and excess[0] == pytest.approx(50 - 10.8)
    assert stages.predicted_torque(samples, q, q, kp, kd).max() <= 10.8


huge = [0.0, 1e-300, 1e6, -1e6, 1e300, -1e300, 1.7e308, -1.7e308]
finite_or_huge = st.one_of(st.floats(-10.0, 10.0), st.sampled_from(huge))


@settings(max_examples=60, deadline=None)
@given(
    q_ref=arrays(np.float64, (B, J), elements=finite_or_huge),
    q=arrays(np.float64, (B, J), elements=finite_or_huge),
    dq=arrays(np.float64, (B, J), elements=finite_or_huge),
    kp=arrays(np.float64, (B, J), elements=st.floats(0.0, 1e6)),
    rho=arrays(np.float64, (B, J), elements=st.floats(0.0, 100.0)),
)
def test_torque_preclip_keeps_the_predicted_torque_under_the_limit(
    q_ref: np.ndarray, q: np.ndarray, dq: np.ndarray, kp: np.ndarray, rho: np.ndarray
) -> None:
    """Any finite state, any gains: outputs finite, gains never raised, torque within limit."""
    limit = 0.9 * FR3.tau_max
    kp_out, kd_out, excess = stages.torque_preclip(q_ref, q, dq, kp, rho, limit)
    torque = stages.predicted_torque(q_ref, q, dq, kp_out, kd_out)
    assert np.all(np.isfinite(kp_out)) and np.all(np.isfinite(kd_out))
    assert np.all(kp_out <= kp) and np.all(kd_out <= stages.damping_gain(kp, rho) + 1e-12)
    assert np.all(torque <= limit * (1 + 1e-12))
    assert np.all(excess >= 0.0)


# --- statistics -------------------------------------------------------------------------


def test_stats_count_and_average_what_was_clipped() -> None:
    applied = np.array([True, True, True, False])
    report = stage_report("joint_limits", applied, np.array([0.0, 0.2, 0.4, 9.0]))
    assert report.clipped.tolist() == [False, True, True, False] and report.excess[3] == 0.0
    stats = summarize(report)
    assert (stats.commands, stats.clipped) == (3, 2)
    assert stats.mean_excess == pytest.approx(0.3) and stats.max_excess == pytest.approx(0.4)
    both = merge(stats, StageStats("joint_limits", 5, 1, 1.2, 1.2))
    assert (both.commands, both.clipped, both.max_excess) == (8, 3, 1.2)
    assert both.mean_excess == pytest.approx((0.2 + 0.4 + 1.2) / 3)


def test_stats_stay_finite_for_huge_excesses() -> None:
    report = stage_report("torque_preclip", np.ones(B, bool), np.array([INF, 1.7e308, 1e308, 0]))
    accumulator = StatsAccumulator()
    accumulator.add((report, report))
    stats = dict((s.stage, s) for s in accumulator.summary())["torque_preclip"]
    assert stats.clipped == 6 and np.isfinite(stats.mean_excess) and np.isfinite(stats.max_excess)
    assert [s.stage for s in accumulator.summary()] == list(STAGE_NAMES)
    accumulator.reset()
    assert all(s.commands == 0 for s in accumulator.summary())


# --- config -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "build",
    [
        lambda: AnnealingConfig(interval=0),
        lambda: AnnealingConfig(num_steps=0),
        lambda: AnnealingConfig(start_step=-1),
        lambda: ActionMagnitudeConfig(squash="sigmoid"),
        lambda: ActionMagnitudeConfig(mode="wrap"),
        lambda: ActionMagnitudeConfig(space="task"),
        lambda: ActionMagnitudeConfig(twist_linear=0.0),
        lambda: ActionMagnitudeConfig(twist_damping=-1e-3),
        lambda: ActionMagnitudeConfig(xi_star_small=0.0),
        lambda: ActionMagnitudeConfig(kp_min=300.0),
        lambda: CartesianClipConfig(eps_x=-0.1),
        lambda: CartesianClipConfig(damping=-1.0),
        lambda: CartesianClipConfig(rows="angular"),
        lambda: CartesianClipConfig(iterations=0),
        lambda: ResidualSmoothingConfig(alpha=0.0),
        lambda: JointLimitsConfig(central_fraction=1.5),
        lambda: TorquePreclipConfig(margin=1.0),
    ],
)
def test_config_rejects_invalid_values(build) -> None:
    with pytest.raises(ValueError):
        build()


def test_default_config_holds_the_papers_values() -> None:
    config = SafetyConfig()
    magnitude, cartesian = config.action_magnitude, config.cartesian_clip
    assert (magnitude.xi_max_large, magnitude.xi_star_large) == (0.26, 0.16)
    assert (magnitude.xi_max_small, magnitude.xi_star_small) == (0.21, 0.08)
    # N_s = 1024 and N_t = 2e6 vectorized steps of 1024 environments, in env_transitions.
    assert (magnitude.annealing.interval, magnitude.annealing.num_steps) == (2**20, 2_048_000_000)
    assert (cartesian.eps_x, cartesian.eps_x_max) == (0.12, 0.24)
    assert config.residual_smoothing.alpha == 0.8
    assert config.joint_limits.central_fraction == 0.9
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.torque_preclip = TorquePreclipConfig()  # type: ignore[misc]
