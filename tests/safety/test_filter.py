"""`SafetyFilter` end to end, stage 6 included, in closed loop with the strict fake FR3 at 1 kHz.

Random and adversarial policy outputs (normal actions with NaN/Inf/huge rows, alternating
extremes) go through the whole pipeline; the references go to two fakes: one with the FR3's
limits (libfranka's reflexes: there must be none) and one with the limits scaled by the dynamics
factor (the reference keeps the limits it was planned with, by finite differences, not by
trusting Ruckig). Each period's measured state is the fake robot's: q its position, dq the last
backward difference. Per period: references finite and in range, predicted torque
kp*|q_ref - q| + kd*|dq| within tau_limit at every sample, and the Cartesian residual within
eps_x by MuJoCo's Jacobian. Then the watchdog's brake, resume, and NaN holds.
Legend: B robots, S = 100 samples per period, J = 7 joints.
"""

from __future__ import annotations

import mujoco
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hamnet.bridge.fake_fr3 import FakeFR3, FakeFR3Config
from hamnet.fr3 import model as fr3_model
from hamnet.fr3.limits import FR3, Q_HOME, FR3Limits
from hamnet.safety import stages
from hamnet.safety.config import ResidualSmoothingConfig, SafetyConfig
from hamnet.safety.filter import SafeOutput, SafetyFilter
from hamnet.safety.pipeline import target_bounds
from hamnet.safety.references import TrajectoryConfig
from hamnet.safety.schedule import per_joint

B, J = 4, 7
KHZ = TrajectoryConfig(control_rate_hz=1000.0)
"""Stage 6 at libfranka's rate: S = 100 references per 0.1 s policy period."""
DT = KHZ.control_period_s
SCALED = FR3Limits(dq_max=KHZ.dq_max, ddq_max=KHZ.ddq_max, jerk_max=KHZ.jerk_max)
"""The limits stage 6 plans with (FR3's scaled by the dynamics factor)."""
MJ_MODEL = fr3_model.load_mujoco()
MJ_DATA = mujoco.MjData(MJ_MODEL)
ROUNDING = 1 + 1e-9


class Loop:
    """A `SafetyFilter` driving B fake FR3s; every period is checked before it is executed."""

    def __init__(self, q: np.ndarray, config: SafetyConfig | None = None) -> None:
        self.filter = SafetyFilter(q, config, KHZ)
        self.config = self.filter.config
        self.fr3 = FakeFR3(q)
        """libfranka's reflexes at the FR3's own limits."""
        self.planned = FakeFR3(q, FakeFR3Config(limits=SCALED))
        """The same checks at the limits stage 6 was given."""
        self.dq = np.zeros_like(q)  # (B, J), rad/s, backward difference of the last tick
        self.step = 0

    @property
    def q(self) -> np.ndarray:
        """Measured positions: where the fake robots are, (B, J), rad."""
        return self.fr3.q

    def command(self, action: object) -> SafeOutput:
        """One policy period: filter the action at the measured state, check, execute."""
        q, dq = self.q, self.dq
        memory = self.filter.core.state.dq_smoothed.copy()  # (B, J) EMA memory before the call
        out = self.filter.command(action, q, dq, self.step)
        self.step += 1
        assert_safe(out, q, dq)
        assert_within_eps_x(self.config, out, q, memory)
        self.execute(out)
        return out

    def brake(self) -> SafeOutput:
        """One period without an action (watchdog)."""
        q, dq = self.q, self.dq
        out = self.filter.brake(q, dq)
        assert_safe(out, q, dq)
        self.execute(out)
        return out

    def execute(self, out: SafeOutput) -> None:
        """Send the references to both fakes; none may refuse a tick."""
        accepted = self.fr3.command(out.q_ref)
        assert np.all(accepted), (self.fr3.errors, out.references.plan)
        assert np.all(self.planned.command(out.q_ref)), self.planned.errors
        np.testing.assert_array_equal(self.q, out.q_ref[:, -1])
        self.dq = (out.q_ref[:, -1] - out.q_ref[:, -2]) / DT


def assert_safe(out: SafeOutput, q: np.ndarray, dq: np.ndarray) -> None:
    """References finite, in the joint range and within the planned velocity and acceleration;
    gains non-negative; kp*|q_ref - q| + kd*|dq| <= tau_limit at every sample."""
    for name in ("q_ref", "dq_ref", "kp", "kd", "tau_limit"):
        assert np.all(np.isfinite(getattr(out, name))), name
    assert np.all((out.q_ref >= FR3.q_min) & (out.q_ref <= FR3.q_max))
    assert np.all(np.abs(out.dq_ref) <= KHZ.dq_max * ROUNDING)
    assert np.all(np.abs(out.references.ddq_ref) <= KHZ.ddq_max * ROUNDING)
    assert np.all(out.kp >= 0.0) and np.all(out.kd >= 0.0)
    assert np.all(out.tau_limit <= FR3.tau_max)
    torque = stages.predicted_torque(out.q_ref, q, dq, out.kp, out.kd)  # (B, J), worst sample
    assert np.all(torque <= out.tau_limit * (1 + 1e-12))
    if out.filtered is not None:
        lo, hi = target_bounds(SafetyConfig())
        assert np.all((out.filtered.q_target >= lo) & (out.filtered.q_target <= hi))


def assert_within_eps_x(
    config: SafetyConfig, out: SafeOutput, q: np.ndarray, memory: np.ndarray
) -> None:
    """||J dq_c|| <= eps_x + (lambda/2)*||xi|| by MuJoCo's Jacobian at the measured q, for the
    residual stage 3 produced in every accepted env: the EMA output less its memory
    (dq_c = (dq_bar - (1 - alpha)*dq_bar_prev)/alpha). The documented DLS slack is
    c*(lambda/2)*||dq_in|| with c <= 1 and ||dq_in|| <= ||xi|| after stage 2."""
    filtered = out.filtered
    smoothing = config.residual_smoothing
    alpha = smoothing.alpha if smoothing.enabled else 1.0
    xi = per_joint(
        filtered.schedule.xi_large,
        filtered.schedule.xi_small,
        config.action_magnitude.num_large_joints,
    )  # (J,)
    tolerance = config.cartesian_clip.damping / 2 * np.linalg.norm(xi) + 1e-9
    for env in np.flatnonzero(~filtered.rejected):
        clamped = (filtered.dq[env] - (1.0 - alpha) * memory[env]) / alpha  # (J,)
        jacobian = fr3_model.mujoco_ee_jacobian(MJ_MODEL, MJ_DATA, q[env])[:3]  # (3, J)
        assert np.linalg.norm(jacobian @ clamped) <= filtered.schedule.eps_x + tolerance


def policy_actions(rng: np.random.Generator, kind: str, periods: int, bad: float) -> np.ndarray:
    """(periods, B, 21) raw actions: "normal" N(0, 1); "extremes" +-3 alternating each period
    (full residual, gains at kp_max or kp_min); "huge" N(0, 1e6). A share `bad` of rows gets
    one NaN, Inf, -Inf or 1e308 entry."""
    shape = (periods, B, stages.ACTION_DIM)
    if kind == "extremes":
        sign = np.where(np.arange(periods) % 2 == 0, 1.0, -1.0)[:, None, None]
        actions = 3.0 * sign * np.where(rng.random(shape) < 0.8, 1.0, -1.0)
    else:
        actions = rng.normal(0.0, 1e6 if kind == "huge" else 1.0, shape)
    rows = rng.random(shape[:2]) < bad  # (periods, B)
    values = rng.choice([np.nan, np.inf, -np.inf, 1e308], size=rows.sum())
    actions[rows, rng.integers(0, stages.ACTION_DIM, size=rows.sum())] = values
    return actions


def random_start(rng: np.random.Generator, b: int = B) -> np.ndarray:
    """(b, J) start positions anywhere in the FR3's range (outside the targets' band too)."""
    return FR3.q_min + rng.uniform(0.02, 0.98, (b, J)) * (FR3.q_max - FR3.q_min)


@settings(max_examples=8, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    kind=st.sampled_from(["normal", "extremes", "huge"]),
    bad=st.sampled_from([0.0, 0.05, 0.3]),
    step=st.integers(0, 3_000_000_000),
    smoothing=st.booleans(),
)
def test_policy_outputs_never_trigger_a_reflex_nor_break_a_bound(
    seed: int, kind: str, bad: float, step: int, smoothing: bool
) -> None:
    """4 robots x 60 periods x 100 ticks: no reflex at the FR3's limits nor at the planned
    ones, and every period passes `assert_safe` and `assert_within_eps_x`."""
    rng = np.random.default_rng(seed)
    config = SafetyConfig(residual_smoothing=ResidualSmoothingConfig(enabled=smoothing))
    loop = Loop(random_start(rng), config)
    loop.step = step
    for action in policy_actions(rng, kind, 60, bad):
        loop.command(action)
    assert np.all(loop.fr3.ticks == 6000) and not loop.fr3.in_reflex.any()


def test_soak_ten_thousand_ticks_per_robot() -> None:
    """Fixed seed, 70 periods of every kind of action (and some wrongly shaped ones) and three
    watchdog stops of half the robots, each braking for 10 periods to rest and resuming there:
    10k ticks per robot, no reflex."""
    rng = np.random.default_rng(2026)
    loop = Loop(np.tile(Q_HOME, (B, 1)))
    kinds = [("normal", 20), ("extremes", 20), ("huge", 15), ("normal", 15)]
    actions = np.concatenate([policy_actions(rng, kind, n, 0.1) for kind, n in kinds])
    for period, action in enumerate(actions):  # (70, B, 21)
        loop.command(action if period % 17 else action[:, :20])  # a wrong shape now and then
        if period % 20 == 19:  # the watchdog fires for half the robots
            stopped = rng.random(B) < 0.5
            loop.filter.stop(stopped)
            for _ in range(10):
                out = loop.brake()
            np.testing.assert_array_equal(out.dq_ref[stopped], 0.0)
            ids = np.flatnonzero(stopped)
            loop.filter.resume(ids, loop.q[ids])
    assert np.all(loop.fr3.ticks == 10_000) and loop.fr3.refused.sum() == 0


def brake_periods() -> int:
    """Policy periods within which a brake from any planned state is at rest: from full speed
    dq_max at full acceleration, first ramp the acceleration down then decelerate, plus a
    period for the one the stop starts in."""
    ramp = KHZ.ddq_max / KHZ.jerk_max  # (J,), s
    seconds = np.max(KHZ.dq_max / KHZ.ddq_max + 3 * ramp)
    return int(np.ceil(seconds / KHZ.policy_period_s)) + 1


def test_watchdog_brakes_to_rest_within_a_bounded_time_and_resumes() -> None:
    """Robots moving fast (alternating full residuals) are stopped: within `brake_periods` the
    velocity references are exactly 0 and the positions hold, every tick accepted; robots not
    stopped keep tracking their last target. Resuming at rest then continues without a
    reflex."""
    rng = np.random.default_rng(3)
    loop = Loop(np.tile(Q_HOME, (B, 1)))
    for action in policy_actions(rng, "extremes", 6, 0.0):
        loop.command(action)
    stopped = np.array([True, True, True, False])
    assert np.all(np.abs(loop.dq[stopped]).max(axis=1) > 0.1)  # really moving
    loop.filter.stop(np.flatnonzero(stopped))
    limit = brake_periods()
    outputs = [loop.brake() for _ in range(limit + 3)]
    assert all(out.stopping.tolist() == stopped.tolist() for out in outputs)
    at_rest = [np.all(out.dq_ref[stopped, -1] == 0.0) for out in outputs]
    first = at_rest.index(True)
    assert first < limit and all(at_rest[first:])
    rest = outputs[first].q_ref[stopped, -1:]  # (3, 1, J)
    for out in outputs[first + 1 :]:
        np.testing.assert_array_equal(out.dq_ref[stopped], 0.0)
        np.testing.assert_array_equal(out.q_ref[stopped], np.broadcast_to(rest, (3, 100, J)))
    held = loop.filter.core.state.q_target[~stopped]  # not stopped: heads to its last target
    np.testing.assert_allclose(outputs[-1].q_ref[~stopped, -1], held, atol=1e-9)
    ids = np.flatnonzero(stopped)
    loop.filter.resume(ids, loop.q[ids])
    for action in policy_actions(rng, "normal", 20, 0.1):
        out = loop.command(action)
        assert not out.stopping.any()
    assert not loop.fr3.in_reflex.any()


def test_resume_while_still_braking_continues_without_a_reflex() -> None:
    """Regression: `resume` re-anchored the references at rest at the measured q, so a robot
    resumed mid-brake (an action arriving one period after the watchdog fired) had its commanded
    velocity jump to 0: velocity and acceleration discontinuity reflexes. The references must
    run on from the brake's state; the fake FR3 checks every tick."""
    rng = np.random.default_rng(3)
    loop = Loop(np.tile(Q_HOME, (B, 1)))
    for action in policy_actions(rng, "extremes", 6, 0.0):
        loop.command(action)
    loop.filter.stop(np.arange(B))
    loop.brake()
    # Still moving: a velocity step of ddq_max*dt = 0.01 rad/s is already a reflex.
    assert np.sum(np.abs(loop.dq).max(axis=1) > 0.05) >= 2
    loop.filter.resume(np.arange(B), loop.q)
    for action in policy_actions(rng, "normal", 10, 0.0):
        out = loop.command(action)
        assert not out.stopping.any() and not out.filtered.rejected.any()
    assert not loop.fr3.in_reflex.any()


@settings(max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_watchdog_at_random_times_never_triggers_a_reflex(seed: int) -> None:
    """Stops, resumes (at rest or mid-brake) and periods without an action (brake) at random
    times among adversarial actions, 60 periods: every period safe, no reflex."""
    rng = np.random.default_rng(seed)
    loop = Loop(random_start(rng))
    for period in range(60):
        if rng.random() < 0.15:
            loop.filter.stop(rng.random(B) < 0.5)
        if rng.random() < 0.15:
            ids = np.flatnonzero(rng.random(B) < 0.5)
            loop.filter.resume(ids, loop.q[ids])
        if rng.random() < 0.2:
            loop.brake()
        else:
            kind = ("normal", "extremes", "huge")[period % 3]
            loop.command(policy_actions(rng, kind, 1, 0.1)[0])
    assert np.all(loop.fr3.ticks == 6000)


def test_policy_actions_while_stopped_are_ignored() -> None:
    """`command` during a stop (a late action before the e-stop is reset) still brakes and holds:
    the action's target never reaches the references."""
    loop = Loop(np.tile(Q_HOME, (B, 1)))
    rng = np.random.default_rng(4)
    for action in policy_actions(rng, "extremes", 3, 0.0):
        loop.command(action)
    loop.filter.stop(np.arange(B))
    outputs = [loop.command(action) for action in policy_actions(rng, "extremes", 10, 0.0)]
    assert all(out.stopping.all() for out in outputs)
    np.testing.assert_array_equal(outputs[-1].dq_ref, 0.0)
    np.testing.assert_array_equal(outputs[-1].q_ref, outputs[-2].q_ref[:, -1:].repeat(100, 1))


def test_nan_actions_hold_the_last_safe_reference() -> None:
    """Moving robots get NaN actions (two of them) or Inf: the target stays the last safe one,
    the references run on continuously from where they were (accepted tick by tick) and come
    to rest on that target; the others keep following their actions."""
    rng = np.random.default_rng(5)
    loop = Loop(np.tile(Q_HOME, (B, 1)))
    for action in policy_actions(rng, "extremes", 4, 0.0):
        last = loop.command(action)
    safe_target = last.filtered.q_target.copy()  # (B, J)
    actions = policy_actions(rng, "normal", 12, 0.0)
    actions[:, 0, 3], actions[:, 1, 15], actions[:, 2, 0] = np.nan, np.nan, np.inf
    held = np.array([True, True, True, False])
    for period, action in enumerate(actions):
        before = loop.filter.trajectory.state  # where the references continue from
        out = loop.command(action)
        np.testing.assert_array_equal(out.filtered.rejected, held)
        np.testing.assert_array_equal(out.filtered.q_target[held], safe_target[held])
        step = np.abs(out.q_ref[:, 0] - before.q)  # first tick: no jump
        assert np.all(step <= KHZ.dq_max * DT * ROUNDING)
    np.testing.assert_allclose(out.q_ref[held, -1], safe_target[held], atol=1e-9)
    np.testing.assert_array_equal(out.dq_ref[held, -1], 0.0)
    assert not np.allclose(out.filtered.q_target[3], safe_target[3])  # env 3 kept moving

