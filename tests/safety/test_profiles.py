"""The filter's named profiles: "training" is the paper's MDP (the clipped, smoothed target on
every control sample, no Ruckig, no Cartesian clip, no torque pre-clip), "finetune" adds the
annealed Cartesian clip, "deploy" is the full chain with Ruckig, unchanged.

Expected values are computed here by hand from the authors' action processing (ham/src/ham/env/
robot/franka.py: affine map of [-1, 1] to the bounds, EMA 0.8 on the residual, target q + dq
clamped to the central 90% of each joint range, kd = rho*sqrt(kp), torque clipped at the FR3's
limit), not with the stage functions.
Legend: B environments, S = 8 control samples per period (80 Hz), J = 7 joints.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from hamnet.fr3 import model as fr3_model
from hamnet.fr3.limits import FR3, Q_HOME
from hamnet.safety.config import PROFILES, SafetyConfig, with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.safety.references import TargetReferences, TrajectoryConfig
from hamnet.safety.ruckig_references import TrajectoryGenerator
from hamnet.safety.schedule import xi_at

B, J = 6, 7
SIM = TrajectoryConfig()
"""80 Hz references, as the sim executes them."""
S = SIM.samples_per_period
MJ_MODEL = fr3_model.load_mujoco()
MJ_DATA = mujoco.MjData(MJ_MODEL)


def start(rng: np.random.Generator) -> np.ndarray:
    """(B, J) positions near home, rad."""
    return Q_HOME + rng.uniform(-0.3, 0.3, (B, J))


def test_profiles_set_the_stage_switches() -> None:
    base = SafetyConfig()
    assert PROFILES == ("training", "finetune", "deploy")
    assert with_profile("deploy") == base
    training, finetune = with_profile("training"), with_profile("finetune")
    assert training.references == finetune.references == "target"
    assert not training.cartesian_clip.enabled and finetune.cartesian_clip.enabled
    for config in (training, finetune):
        assert not config.torque_preclip.enabled and config.torque_preclip.margin == 0.0
        assert config.action_magnitude == base.action_magnitude
        assert config.residual_smoothing == base.residual_smoothing
        assert config.joint_limits == base.joint_limits
    with pytest.raises(ValueError):
        with_profile("evaluation")  # type: ignore[arg-type]


def test_training_profile_sends_the_clipped_smoothed_target_on_every_sample() -> None:
    """No Ruckig smoothing: q_ref[:, s] is the target of the authors' processing for every s,
    episode after episode; gains are the action's, the torque limit the FR3's."""
    rng = np.random.default_rng(0)
    q = start(rng)
    counter = 300_000_000  # env_transitions: xi partly annealed
    flt = SafetyFilter(q, with_profile("training"), SIM)
    assert isinstance(flt.trajectory, TargetReferences)
    xi_large, xi_small = xi_at(counter, SafetyConfig().action_magnitude)
    xi = np.array([xi_large] * 4 + [xi_small] * 3)  # (J,)
    centre, half = (FR3.q_max + FR3.q_min) / 2, (FR3.q_max - FR3.q_min) / 2
    lo, hi = centre - 0.9 * half, centre + 0.9 * half  # rel_clamp_joint_target [-0.9, 0.9]
    memory = np.zeros((B, J))
    for _ in range(5):
        action = rng.normal(0.0, 1.5, (B, 21))
        u = np.clip(action, -1.0, 1.0)
        memory = 0.8 * xi * u[:, :J] + 0.2 * memory  # ema_action 0.8
        target = np.clip(q + memory, lo, hi)  # (B, J)
        kp = 10.0 + (u[:, J : 2 * J] + 1.0) / 2.0 * 190.0
        rho = 0.3 + (u[:, 2 * J :] + 1.0) / 2.0 * 1.7
        out = flt.command(action, q, np.zeros((B, J)), counter)
        assert out.q_ref.shape == (B, S, J)
        np.testing.assert_allclose(out.q_ref, np.repeat(target[:, None], S, axis=1), atol=1e-12)
        np.testing.assert_allclose(out.kp, kp, rtol=1e-12)
        np.testing.assert_allclose(out.kd, rho * np.sqrt(kp), rtol=1e-12)
        np.testing.assert_array_equal(out.tau_limit, np.tile(FR3.tau_max, (B, 1)))
        assert not out.dq_ref.any()
        q = target + rng.normal(0.0, 0.01, (B, J))  # the robot lands near its target


def test_training_profile_differs_from_deploy_only_in_what_the_paper_leaves_out() -> None:
    """Same inputs: deploy's Ruckig ramps towards the target (not reached on the first
    sample), training jumps to it; with the Cartesian clip and pre-clip off in deploy and the
    torque margin zero, the targets agree."""
    rng = np.random.default_rng(1)
    q, action = start(rng), rng.normal(0.0, 1.5, (B, 21))
    training = SafetyFilter(q, with_profile("training"), SIM)
    plain = with_profile("training")
    deploy = SafetyFilter(q, dataclasses.replace(plain, references="ruckig"), SIM)
    assert isinstance(deploy.trajectory, TrajectoryGenerator)
    a = training.command(action, q, np.zeros((B, J)), 0)
    b = deploy.command(action, q, np.zeros((B, J)), 0)
    np.testing.assert_allclose(a.filtered.q_target, b.filtered.q_target)
    assert np.abs(b.q_ref[:, 0] - a.q_ref[:, 0]).max() > 1e-3  # Ruckig starts at rest


def test_finetune_profile_bounds_the_cartesian_step() -> None:
    """First period of an episode (EMA memory empty): ||J (q_ref - q)|| <= alpha*eps_x (plus the
    damped least squares' slack) by MuJoCo's Jacobian, on every sample; training exceeds it."""
    rng = np.random.default_rng(2)
    q = start(rng)
    action = np.sign(rng.normal(size=(B, 21))) * 3.0  # residuals at the bound
    config = with_profile("finetune")
    eps_x, damping = config.cartesian_clip.eps_x_max, config.cartesian_clip.damping
    alpha = config.residual_smoothing.alpha
    fine = SafetyFilter(q, config, SIM).command(action, q, np.zeros((B, J)), 0)
    free = SafetyFilter(q, with_profile("training"), SIM).command(action, q, np.zeros((B, J)), 0)
    motion_fine, motion_free = [], []
    for env in range(B):
        jacobian = fr3_model.mujoco_ee_jacobian(MJ_MODEL, MJ_DATA, q[env])[:3]  # (3, J)
        step = fine.q_ref[env] - q[env]  # (S, J)
        slack = damping / 2 * np.linalg.norm(step[0]) + 1e-9
        motion_fine.append(np.linalg.norm(step @ jacobian.T, axis=1).max() - slack)
        motion_free.append(np.linalg.norm(jacobian @ (free.q_ref[env, 0] - q[env])))
    assert max(motion_fine) <= alpha * eps_x
    assert max(motion_free) > alpha * eps_x  # the bound is active for these actions
    assert fine.filtered.schedule.eps_x == eps_x


def test_deploy_profile_is_the_default_filter() -> None:
    """Same inputs, same outputs as the service's default: Ruckig and the pre-clip stay."""
    rng = np.random.default_rng(3)
    q = start(rng)
    default, deploy = SafetyFilter(q, None, SIM), SafetyFilter(q, with_profile("deploy"), SIM)
    for _ in range(3):
        action = rng.normal(0.0, 1.5, (B, 21))
        a = default.command(action, q, np.zeros((B, J)), 0)
        b = deploy.command(action, q, np.zeros((B, J)), 0)
        for name in ("q_ref", "dq_ref", "kp", "kd", "tau_limit"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert np.abs(np.diff(a.q_ref, axis=1)).max() > 0.0  # a ramp, not a step
        np.testing.assert_allclose(a.tau_limit, np.tile(0.9 * FR3.tau_max, (B, 1)))
        q = a.q_ref[:, -1]


def test_target_references_hold_while_stopped() -> None:
    """The watchdog's path in the training profile: a stopped environment keeps its last
    reference whatever the policy sends, and follows targets again after `resume`."""
    rng = np.random.default_rng(4)
    q = start(rng)
    refs = TargetReferences(q, SIM)
    first = q + 0.1
    refs.step(first)
    refs.stop(np.array([0]))
    out = refs.step(first + 0.2)
    np.testing.assert_array_equal(out.q_ref[0], np.repeat(first[:1], S, axis=0))
    np.testing.assert_allclose(out.q_ref[1:, -1], first[1:] + 0.2)
    assert out.plan[0] == 1 and not out.plan[1:].any()
    refs.resume(np.array([0]))
    np.testing.assert_allclose(refs.step(first + 0.3).q_ref[0, 0], first[0] + 0.3)
