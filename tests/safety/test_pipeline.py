"""The safety core end to end: a hand-computed batch, holds after rejections, episode starts,
statistics, the stage-6 seam, every stage switched off, and hypothesis properties over
adversarial actions and states (NaN, Inf, huge values): outputs finite, targets inside the
joint band, predicted torque under the limit, ||J dq|| <= eps_x by MuJoCo's Jacobian."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hamnet.fr3 import model as fr3_model
from hamnet.fr3.limits import FR3, Q_HOME
from hamnet.safety import stages
from hamnet.safety.cartesian import ee_jacobians
from hamnet.safety.config import CartesianClipConfig, SafetyConfig
from hamnet.safety.pipeline import (
    FilterResult,
    SafetyCore,
    filter_action,
    initial_state,
    target_bounds,
)
from hamnet.safety.stages import Rejection
from hamnet.safety.stats import STAGE_NAMES

B, J = 4, 7
NAN, INF = float("nan"), float("inf")
PIN_MODEL, PIN_DATA = fr3_model.load_pinocchio()
MJ_MODEL = fr3_model.load_mujoco()
MJ_DATA = mujoco.MjData(MJ_MODEL)
LO, HI = target_bounds(SafetyConfig())
TAU_LIMIT = 0.9 * FR3.tau_max


def jacobians(q: np.ndarray) -> np.ndarray:
    return ee_jacobians(PIN_MODEL, PIN_DATA, q, "full")


def home(b: int = B) -> np.ndarray:
    return np.tile(Q_HOME, (b, 1))


def no_cartesian() -> SafetyConfig:
    return SafetyConfig(cartesian_clip=CartesianClipConfig(enabled=False))


def assert_safe(result: FilterResult, q: np.ndarray, dq: np.ndarray) -> None:
    """The invariants every command must meet, checked on rows with a finite state."""
    for name in ("q_target", "kp", "kd", "rho", "tau_limit", "dq"):
        assert np.all(np.isfinite(getattr(result, name))), name
    assert np.all((result.q_target >= LO) & (result.q_target <= HI))
    assert np.all(result.tau_limit <= FR3.tau_max) and np.all(result.kp >= 0.0)
    ok = np.isfinite(q).all(axis=1) & np.isfinite(dq).all(axis=1)
    torque = stages.predicted_torque(result.q_target, q, dq, result.kp, result.kd)
    assert np.all(torque[ok] <= result.tau_limit[ok] * (1 + 1e-12))
    for report in result.reports:
        assert np.all(np.isfinite(report.excess)) and np.all(report.clipped <= report.applied)


def paddle_position(q: np.ndarray) -> np.ndarray:
    """(3,) the paddle's position at the joint positions q (J,), by Pinocchio."""
    pin.framesForwardKinematics(PIN_MODEL, PIN_DATA, q)
    return PIN_DATA.oMf[PIN_MODEL.getFrameId(fr3_model.EE_SITE)].translation.copy()


def test_paddle_space_moves_the_paddle_by_the_asked_twist() -> None:
    """In "paddle" space (EMA off, so one step's target is the whole residual) the target
    posture moves the paddle by the asked translation, 1-3 cm along each axis from home, to
    within 1 mm (first-order DLS), while the joint-space reading of the same action does not."""
    config = no_cartesian()
    config = dataclasses.replace(
        config,
        action_magnitude=dataclasses.replace(config.action_magnitude, space="paddle"),
        residual_smoothing=dataclasses.replace(config.residual_smoothing, enabled=False),
    )
    asked = np.array([[0.01, 0, 0], [0, -0.02, 0], [0, 0, 0.01], [0.01, 0.01, -0.01]])  # m
    action = np.zeros((B, 21))
    action[:, :3] = asked / config.action_magnitude.twist_linear
    q = home()
    result, _ = filter_action(
        config, initial_state(B, config), action, q, np.zeros((B, J)), 0, jacobians
    )
    moved = np.array(
        [paddle_position(t) - paddle_position(q0) for t, q0 in zip(result.q_target, q)]
    )
    np.testing.assert_allclose(moved, asked, atol=1e-3)
    joint = dataclasses.replace(
        config, action_magnitude=dataclasses.replace(config.action_magnitude, space="joint")
    )
    result, _ = filter_action(
        joint, initial_state(B, joint), action, q, np.zeros((B, J)), 0, jacobians
    )
    moved = np.array(
        [paddle_position(t) - paddle_position(q0) for t, q0 in zip(result.q_target, q)]
    )
    assert np.abs(moved - asked).max() > 0.01


def test_one_batch_by_hand() -> None:
    """No Cartesian clip, step 0 (xi = 0.26/0.21), zero EMA memory: target = q + 0.8*xi*u.
    Env 0: u = 0.5 on joint 1 -> +0.104 rad, kp 105 (u = 0), rho 1.15.
    Env 1: u = 1 on joint 4 from -0.2 -> -0.2 + 0.208 = 0.008, clipped to hi_4 = -0.264905.
    Env 2: NaN -> holds q (its first target), hold gains kp 100, rho 1.
    Env 3: kp u = 1 (200) with a joint-5 error 0.8*0.21 = 0.168 rad: 33.6 N m > 10.8 N m."""
    q = home()
    q[1, 3] = -0.2
    action = np.zeros((B, 21))
    action[0, 0] = 0.5
    action[1, 3] = 1.0
    action[2, 2] = NAN
    action[3, 4], action[3, 11] = 1.0, 1.0
    dq = np.zeros((B, J))
    config = no_cartesian()
    result, _ = filter_action(config, initial_state(B, config), action, q, dq, 0, jacobians)
    assert result.reasons() == ["ACCEPTED", "ACCEPTED", "NONFINITE", "ACCEPTED"]
    assert result.q_target[0, 0] == pytest.approx(0.104)
    assert result.kp[0, 0] == pytest.approx(105.0) and result.rho[0, 0] == pytest.approx(1.15)
    assert result.kd[0, 0] == pytest.approx(1.15 * np.sqrt(105.0))
    assert result.q_target[1, 3] == pytest.approx(-0.1169 - 0.148005)
    np.testing.assert_allclose(result.q_target[2], Q_HOME)
    assert np.all(result.kp[2] == 100.0) and np.all(result.dq[2] == 0.0)
    w2 = 10.8 / 33.6  # error-only torque: kp scales by limit/torque
    assert result.kp[3, 4] == pytest.approx(200.0 * w2, rel=1e-8)
    assert result.kd[3, 4] == pytest.approx(result.rho[3, 4] * np.sqrt(200.0 * w2), rel=1e-8)
    np.testing.assert_allclose(result.tau_limit, np.tile(TAU_LIMIT, (B, 1)))
    stats = {s.stage: s for s in result.stats}
    assert (stats["nonfinite_guard"].commands, stats["nonfinite_guard"].clipped) == (4, 1)
    assert stats["joint_limits"].clipped == 1
    assert stats["joint_limits"].max_excess == pytest.approx(0.008 + 0.264905)
    assert stats["cartesian_clip"].commands == 0  # switched off
    assert stats["torque_preclip"].clipped >= 1 and stats["action_magnitude"].clipped == 0
    assert_safe(result, q, dq)


def test_rejected_env_holds_its_last_safe_target_and_ema_memory() -> None:
    core = SafetyCore(B, no_cartesian())
    q, dq = home(), np.zeros((B, J))
    first = np.zeros((B, 21))
    first[:, 0] = 1.0  # joint 1: u = 1 -> dq_bar = 0.8*0.26 = 0.208
    one = core.filter(first, q, dq, step=0)
    np.testing.assert_allclose(one.q_target[:, 0], 0.208)
    bad = first.copy()
    bad[1, 3], bad[2, 7] = INF, NAN
    two = core.filter(bad, q, dq, step=0)
    assert two.rejected.tolist() == [False, True, True, False]
    np.testing.assert_array_equal(two.q_target[1:3], one.q_target[1:3])
    np.testing.assert_allclose(two.q_target[[0, 3], 0], 0.208 + 0.2 * 0.208)
    three = core.filter(first, q, dq, step=0)
    # EMA: envs 1-2 skipped step two, so their memory is still 0.208, not 0.2496.
    np.testing.assert_allclose(three.q_target[1:3, 0], 0.208 + 0.2 * 0.208)
    np.testing.assert_allclose(three.q_target[[0, 3], 0], 0.208 + 0.2 * (0.208 + 0.2 * 0.208))


def test_shape_errors_reject_every_env_and_state_errors_raise() -> None:
    core = SafetyCore(B)
    q, dq = home(), np.zeros((B, J))
    result = core.filter(np.zeros((B, 20)), q, dq, step=0)
    assert np.all(result.reason == Rejection.SHAPE)
    np.testing.assert_allclose(result.q_target, q)
    assert_safe(result, q, dq)
    with pytest.raises(ValueError):
        core.filter(np.zeros((B, 21)), q[:3], dq[:3], step=0)
    with pytest.raises(ValueError):
        core.reset(np.zeros((B, 6)))


def test_nonfinite_state_holds_without_a_torque_guess() -> None:
    """A NaN joint reading rejects that env (STATE); a first-ever NaN state holds home."""
    core = SafetyCore(B)
    q, dq = home(), np.zeros((B, J))
    q[0, 2], dq[1, 5] = NAN, INF
    result = core.filter(np.zeros((B, 21)), q, dq, step=0)
    assert result.reason.tolist() == [Rejection.STATE, Rejection.STATE, 0, 0]
    np.testing.assert_allclose(result.q_target[0], np.clip(Q_HOME, LO, HI))
    assert_safe(result, q, dq)


def test_episode_start_clears_the_ema_and_resets_the_hold() -> None:
    core = SafetyCore(B, no_cartesian())
    q, dq = home(), np.zeros((B, J))
    action = np.zeros((B, 21))
    action[:, 0] = 1.0
    core.filter(action, q, dq, step=0)
    q_new = home()
    q_new[:, 0] = 0.5
    start = np.array([True, False, False, False])
    result = core.filter(action, q_new, dq, step=0, episode_start=start)
    assert result.q_target[0, 0] == pytest.approx(0.5 + 0.208)  # fresh memory
    assert result.q_target[1, 0] == pytest.approx(0.5 + 0.208 + 0.2 * 0.208)
    core.reset(q_new, env_ids=[2])
    bad = action.copy()
    bad[2, 0] = NAN
    held = core.filter(bad, q_new, dq, step=0)
    np.testing.assert_allclose(held.q_target[2], q_new[2])  # the reset's hold, not the old one


def test_annealed_bounds_reach_the_papers_targets() -> None:
    core = SafetyCore(B, no_cartesian())
    action = np.ones((B, 21))
    result = core.filter(action, home(), np.zeros((B, J)), step=3 * 10**9)
    papers = {"xi_large": 0.16, "xi_small": 0.08, "eps_x": 0.12}
    assert result.schedule.as_dict() == pytest.approx(papers)
    np.testing.assert_allclose(result.dq[0], 0.8 * np.array([0.16] * 4 + [0.08] * 3))


def test_statistics_accumulate_what_each_stage_clipped() -> None:
    core = SafetyCore(B)
    q, dq = home(), np.zeros((B, J))
    action = np.zeros((B, 21))
    action[0, :7] = 3.0  # saturated and a large Cartesian push
    action[1, 0] = NAN
    for _ in range(3):
        core.filter(action, q, dq, step=0)
    stats = {s.stage: s for s in core.stats.summary()}
    assert [s.stage for s in core.stats.summary()] == list(STAGE_NAMES)
    assert (stats["nonfinite_guard"].commands, stats["nonfinite_guard"].clipped) == (12, 3)
    assert (stats["action_magnitude"].commands, stats["action_magnitude"].clipped) == (9, 3)
    assert stats["action_magnitude"].max_excess == pytest.approx(2 * 0.26)
    assert stats["cartesian_clip"].clipped == 3 and stats["cartesian_clip"].mean_excess > 0.0
    core.stats.reset()
    assert all(s.commands == 0 for s in core.stats.summary())


def test_recheck_lowers_gains_for_an_overshooting_reference() -> None:
    """Stage 6 seam: a reference that overshoots the target mid-period gets gains for its
    worst sample; gains never rise."""
    core = SafetyCore(B, no_cartesian())
    q, dq = home(), np.zeros((B, J))
    action = np.zeros((B, 21))
    action[:, 7:14] = 1.0  # kp = 200
    result = core.filter(action, q, dq, step=0, record=False)
    samples = np.repeat(result.q_target[:, None, :], 5, axis=1)  # (B, S, J)
    samples[0, 2, 0] += 0.6  # 200*0.6 = 120 N m > 78.3 N m
    checked = core.recheck_torque(result, samples, q, dq)
    assert np.all(checked.kp <= result.kp) and checked.kp[0, 0] < result.kp[0, 0]
    torque = stages.predicted_torque(samples, q, dq, checked.kp, checked.kd)
    assert np.all(torque <= checked.tau_limit)
    report = {r.stage: r for r in checked.reports}["torque_preclip"]
    assert report.clipped[0] and report.excess[0] == pytest.approx(200 * 0.6 - 78.3, rel=1e-6)
    core.record(checked)
    assert {s.stage: s for s in core.stats.summary()}["torque_preclip"].commands == B


@pytest.mark.parametrize("stage", STAGE_NAMES)
def test_every_stage_can_be_switched_off(stage: str) -> None:
    config = SafetyConfig()
    off = dataclasses.replace(getattr(config, stage), enabled=False)
    config = dataclasses.replace(config, **{stage: off})
    core = SafetyCore(B, config)
    rng = np.random.default_rng(1)
    q = home() + rng.normal(scale=0.1, size=(B, J))
    dq = rng.normal(scale=0.5, size=(B, J))
    for step in (0, 10**7):
        result = core.filter(rng.normal(size=(B, 21)), q, dq, step=step)
        assert result.q_target.shape == result.kp.shape == result.kd.shape == (B, J)
        assert np.all(np.isfinite(result.q_target)) and np.all(np.isfinite(result.kd))
    off = {r.stage: r for r in result.reports}[stage]
    assert not off.applied.any() and not off.clipped.any()


# --- properties ---------------------------------------------------------------------------

adversarial = st.sampled_from([NAN, INF, -INF, 1e308, -1e308, 1e6, -1e6, 0.0])
action_values = st.one_of(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), adversarial)
unit_box = arrays(np.float64, (B, J), elements=st.floats(0.0, 1.0))


@st.composite
def robot_states(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    """q anywhere in the FR3 box (rows sometimes replaced by adversarial values), dq mostly
    plausible but sometimes huge or non-finite."""
    q = FR3.q_min + draw(unit_box) * (FR3.q_max - FR3.q_min)  # (B, J)
    dq = draw(arrays(np.float64, (B, J), elements=st.floats(-5.0, 5.0)))
    for array in (q, dq):
        for env in draw(st.lists(st.integers(0, B - 1), max_size=2)):
            array[env, draw(st.integers(0, J - 1))] = draw(adversarial)
    return q, dq


@settings(max_examples=60, deadline=None)
@given(
    first=arrays(np.float64, (B, 21), elements=st.floats(-3.0, 3.0)),
    second=arrays(np.float64, (B, 21), elements=action_values),
    state=robot_states(),
    step=st.integers(0, 3_000_000_000),
)
def test_every_command_is_safe_under_adversarial_inputs(
    first: np.ndarray, second: np.ndarray, state: tuple[np.ndarray, np.ndarray], step: int
) -> None:
    """Two steps (a sane action, then an adversarial one with an adversarial state): every
    output finite, targets inside the central 90%, predicted torque within (1-margin)*tau_max,
    rejected envs on their previous safe target, and stats consistent with the masks."""
    config = SafetyConfig()
    q, dq = state
    state0 = initial_state(B, config)
    one, after = filter_action(config, state0, first, home(), np.zeros((B, J)), step, jacobians)
    two, _ = filter_action(config, after, second, q, dq, step, jacobians)
    assert_safe(one, home(), np.zeros((B, J)))
    assert_safe(two, q, dq)
    finite = [np.isfinite(array).all(axis=1) for array in (second, q, dq)]
    expected = ~(finite[0] & finite[1] & finite[2])  # (B,) rejected
    np.testing.assert_array_equal(two.rejected, expected)
    np.testing.assert_array_equal(two.q_target[two.rejected], one.q_target[two.rejected])
    stats = {s.stage: s for s in two.stats}
    assert stats["nonfinite_guard"].clipped == expected.sum()
    assert stats["action_magnitude"].commands == (~expected).sum()
    assert stats["torque_preclip"].commands == B


@settings(max_examples=40, deadline=None)
@given(
    action=arrays(np.float64, (B, 21), elements=st.one_of(st.floats(-3.0, 3.0), adversarial)),
    u=unit_box,
    step=st.integers(0, 3_000_000_000),
)
def test_pipeline_residual_meets_eps_x_by_mujocos_jacobian(
    action: np.ndarray, u: np.ndarray, step: int
) -> None:
    """EMA off so the output residual is stage 3's: ||J_mujoco dq|| <= eps_x + (lambda/2)*||dq||
    for every accepted env, with eps_x from the annealing schedule at `step`."""
    smoothing_off = dataclasses.replace(SafetyConfig().residual_smoothing, enabled=False)
    config = SafetyConfig(residual_smoothing=smoothing_off)
    q = FR3.q_min + u * (FR3.q_max - FR3.q_min)
    state = initial_state(B, config)
    result, _ = filter_action(config, state, action, q, np.zeros((B, J)), step, jacobians)
    damping = config.cartesian_clip.damping
    for env in np.flatnonzero(~result.rejected):
        jacobian = fr3_model.mujoco_ee_jacobian(MJ_MODEL, MJ_DATA, q[env])[:3]
        motion = np.linalg.norm(jacobian @ result.dq[env])
        tolerance = damping / 2 * np.linalg.norm(result.dq[env]) + 1e-9
        assert motion <= result.schedule.eps_x + tolerance
