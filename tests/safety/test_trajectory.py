"""Stage 6 (hamnet.safety.ruckig_references): jerk-limited references within the scaled FR3 limits.

Limits are checked on the sampled reference by backward finite differences, never by trusting
Ruckig's numbers. Tolerance: a reference whose position, velocity and acceleration are
continuous and whose jerk is bounded has finite differences that are weighted averages of the
true derivative over the stencil (Delta^k q / dt^k = integral of q^(k) against a B-spline
kernel >= 0 of unit mass), so in exact arithmetic they never exceed the limit at any sampling
rate. What is left is float64 rounding (about 8 eps |q| / dt^3 = 1e-5 rad/s^3 for a third
difference at 1 kHz, 2e-9 of the jerk limit) and Ruckig's own 1e-12 slack on its limits, so
`FD_RTOL` = 1e-6 of each limit is ample and still catches any real violation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import ruckig
from hypothesis import given, settings
from hypothesis import strategies as st

from hamnet.fr3.limits import FR3, Q_HOME
from hamnet.safety.references import Plan, References, TrajectoryConfig
from hamnet.safety.ruckig_references import TrajectoryGenerator, position_extrema

FD_RTOL = 1e-6
"""Allowed excess of a finite difference over its limit, as a fraction (module docstring)."""

B = 4
J = 7
Q_MIN, Q_MAX = np.asarray(FR3.q_min), np.asarray(FR3.q_max)

SCENARIOS = ("uniform", "limits", "alternate", "hold", "behind", "ahead", "beyond", "nan", "stop")
"""Target patterns for one period: random in range, each joint at a limit, far targets that
alternate every period, the current position (stop while moving), just behind and just ahead of
the motion (overshoot towards limits), beyond the range (the caller should have clipped), a
non-finite target, and a watchdog stop."""


def scenario_targets(
    scenario: str, period: int, generator: TrajectoryGenerator, rng: np.random.Generator
) -> np.ndarray:
    """Targets for one period, (B, J), rad; also applies `stop`/`resume` for "stop"."""
    state = generator.state
    direction = np.sign(state.dq)  # (B, J)
    uniform = rng.uniform(Q_MIN, Q_MAX, size=(B, J))  # (B, J)
    generator.resume(np.arange(B))
    if scenario == "limits":
        return np.where(rng.random((B, J)) < 0.5, Q_MIN, Q_MAX)
    if scenario == "alternate":
        return np.tile(Q_MAX if period % 2 else Q_MIN, (B, 1))
    if scenario == "hold":
        return state.q
    if scenario == "behind":
        return state.q - 0.3 * direction * rng.random((B, J))
    if scenario == "ahead":
        return state.q + 0.05 * direction * rng.random((B, J))
    if scenario == "beyond":
        return np.where(rng.random((B, J)) < 0.5, Q_MIN - 1.0, Q_MAX + 1.0)
    if scenario == "nan":
        uniform[rng.integers(B), rng.integers(J)] = np.nan
    if scenario == "stop":
        generator.stop(rng.random(B) < 0.5)
    return uniform


def run(
    generator: TrajectoryGenerator, scenarios: list[str], rng: np.random.Generator
) -> list[References]:
    """Step the generator once per scenario; the references of every period."""
    return [
        generator.step(scenario_targets(name, k, generator, rng))
        for k, name in enumerate(scenarios)
    ]


def concatenated(start_q: np.ndarray, references: list[References]) -> np.ndarray:
    """The reference as one signal with its rest before the first period, (B, 3 + T, J)."""
    rest = np.repeat(start_q[:, None], 3, axis=1)  # (B, 3, J)
    return np.concatenate([rest] + [r.q_ref for r in references], axis=1)


def assert_within_limits(q: np.ndarray, dq_ref: np.ndarray, config: TrajectoryConfig) -> None:
    """Finite, inside the joint range, and velocity, acceleration and jerk of q by backward
    differences within the FR3's limits times the dynamics factor (computed here, not taken
    from the config's own properties).

    Args:
        q: resting history then samples, (B, 3 + T, J), rad.
        dq_ref: sampled velocities, (B, T, J), rad/s.
    """
    dt = 1.0 / config.control_rate_hz
    factor = config.dynamics_factor
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(dq_ref))
    assert np.all(q >= Q_MIN) and np.all(q <= Q_MAX)
    velocity = np.diff(q, axis=1) / dt  # (B, 2 + T, J)
    acceleration = np.diff(velocity, axis=1) / dt  # (B, 1 + T, J)
    jerk = np.diff(acceleration, axis=1) / dt  # (B, T, J)
    for name, value, limit in (
        ("velocity", velocity, factor * FR3.dq_max),
        ("sampled velocity", dq_ref, factor * FR3.dq_max),
        ("acceleration", acceleration, factor * FR3.ddq_max),
        ("jerk", jerk, factor * FR3.jerk_max),
    ):
        worst = np.max(np.abs(value) / limit)
        assert worst <= 1.0 + FD_RTOL, f"{name} at {worst:.6f} of its limit"


def assert_continuous(start: np.ndarray, references: list[References], config: TrajectoryConfig):
    """Across each period boundary, position, velocity and acceleration change by no more than
    their limits allow in one sample (the next plan starts where the last one ended)."""
    dt = config.control_period_s
    previous = (start, np.zeros_like(start), np.zeros_like(start))  # rest, (B, J) each
    for ref in references:
        first = (ref.q_ref[:, 0], ref.dq_ref[:, 0], ref.ddq_ref[:, 0])  # (B, J) each
        for before, after, rate in zip(previous, first, (config.dq_max, config.ddq_max,
                                                          config.jerk_max)):  # fmt: skip
            assert np.all(np.abs(after - before) <= rate * dt * (1.0 + FD_RTOL))
        end = ref.end_state
        previous = (end.q, end.dq, end.ddq)


def test_limit_check_catches_a_position_step() -> None:
    """The checker itself can fail: a 1 mrad step at 1 kHz is a velocity of 1 rad/s but an
    acceleration of 1000 rad/s^2, far beyond the limit."""
    config = TrajectoryConfig(control_rate_hz=1000.0)
    q = np.tile(Q_HOME, (1, 10, 1))  # (1, 10, J)
    q[:, 6:, 0] += 1e-3
    with pytest.raises(AssertionError, match="acceleration"):
        assert_within_limits(q, np.zeros((1, 7, J)), config)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    scenarios=st.lists(st.sampled_from(SCENARIOS), min_size=4, max_size=24),
    dynamics_factor=st.sampled_from([0.5, 1.0]),
    control_rate_hz=st.sampled_from([80.0, 1000.0]),
)
def test_references_stay_within_limits_and_continuous(
    seed: int, scenarios: list[str], dynamics_factor: float, control_rate_hz: float
) -> None:
    config = TrajectoryConfig(dynamics_factor=dynamics_factor, control_rate_hz=control_rate_hz)
    rng = np.random.default_rng(seed)
    start = rng.uniform(Q_MIN, Q_MAX, size=(B, J))  # (B, J)
    generator = TrajectoryGenerator(start, config)
    references = run(generator, scenarios, rng)
    q = concatenated(start, references)  # (B, 3 + T, J)
    dq_ref = np.concatenate([r.dq_ref for r in references], axis=1)  # (B, T, J)
    assert_within_limits(q, dq_ref, config)
    assert_continuous(start, references, config)
    assert np.array_equal(generator.state.q, references[-1].end_state.q)
    assert np.array_equal(generator.state.ddq, references[-1].end_state.ddq)


def one_joint_plan(
    q: float, dq: float, ddq: float, target: float, velocity_interface: bool = False
) -> ruckig.Trajectory:
    """A Ruckig plan of joint 0 within the default scaled limits (the others at rest)."""
    config = TrajectoryConfig()
    inp = ruckig.InputParameter(J)
    inp.max_velocity = config.dq_max.tolist()
    inp.max_acceleration = config.ddq_max.tolist()
    inp.max_jerk = config.jerk_max.tolist()
    inp.current_position = [q] + [0.0] * (J - 1)
    inp.current_velocity = [dq] + [0.0] * (J - 1)
    inp.current_acceleration = [ddq] + [0.0] * (J - 1)
    inp.target_position = [target] + [0.0] * (J - 1)
    if velocity_interface:
        inp.control_interface = ruckig.ControlInterface.Velocity
    trajectory = ruckig.Trajectory(J)
    ruckig.Ruckig(J).calculate(inp, trajectory)
    return trajectory


def dense_positions(trajectory: ruckig.Trajectory) -> np.ndarray:
    """Positions at 4001 instants over the whole plan, (4001, J), rad."""
    times = np.linspace(0.0, trajectory.duration, 4001)
    return np.array([trajectory.at_time(t)[0] for t in times])


def test_position_extrema_see_the_overshoot_ruckig_misses() -> None:
    """At full speed towards q_max with the target behind, the plan overshoots by 0.17 rad
    inside a constant-deceleration phase; ruckig 0.19.4's `position_extrema` reported the
    start instead, which let a plan past q_max through the range guard."""
    trajectory = one_joint_plan(2.8507, 1.31, 0.0, 0.0)
    low, high = position_extrema([trajectory])  # (1, J) each
    dense = dense_positions(trajectory)[:, 0]  # (4001,)
    assert dense.max() > 3.02
    assert dense.max() <= high[0, 0] <= dense.max() + 1e-6
    assert low[0, 0] == pytest.approx(0.0, abs=1e-8)


@settings(max_examples=60, deadline=None)
@given(
    dq=st.floats(-1.5, 1.5),
    ddq=st.floats(-6.0, 6.0),
    target=st.floats(-2.0, 2.0),
    velocity_interface=st.booleans(),
)
def test_position_extrema_bound_the_plan_tightly(
    dq: float, ddq: float, target: float, velocity_interface: bool
) -> None:
    """Against 4001 samples of the plan, states beyond the limits included (Ruckig then
    prepends brake phases): never inside the sampled range, and at most the sampling's
    resolution outside it (at an extremum v = 0, so |a| (T / 8000)^2 / 2 < 1e-5 rad)."""
    trajectory = one_joint_plan(0.3, dq, ddq, target, velocity_interface)
    low, high = position_extrema([trajectory])  # (1, J) each
    dense = dense_positions(trajectory)  # (4001, J)
    assert np.all(low[0] <= dense.min(axis=0) + 1e-12)
    assert np.all(high[0] >= dense.max(axis=0) - 1e-12)
    assert np.all(dense.min(axis=0) - low[0] < 1e-5)
    assert np.all(high[0] - dense.max(axis=0) < 1e-5)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dynamics_factor=st.sampled_from([0.5, 1.0]))
def test_fixed_far_target_is_reached_in_time_and_held(seed: int, dynamics_factor: float) -> None:
    """From one end of the range to the other: reached within the time a jerk-limited
    trapezoid needs on the slowest joint (d/v + v/a + a/j), then held exactly at rest."""
    config = TrajectoryConfig(dynamics_factor=dynamics_factor)
    rng = np.random.default_rng(seed)
    low, high = Q_MIN + 0.05, Q_MAX - 0.05
    start = np.where(rng.random((B, J)) < 0.5, low, high)  # (B, J)
    target = np.where(start == low, high, low)  # (B, J)
    v, a, j = config.dq_max, config.ddq_max, config.jerk_max
    duration = np.max(np.abs(target - start) / v + v / a + a / j)
    periods = math.ceil(duration / config.policy_period_s) + 1
    generator = TrajectoryGenerator(start, config)
    for _ in range(periods):
        ref = generator.step(target)
    assert np.all(ref.reached) and np.all(ref.plan == Plan.TARGET)
    np.testing.assert_allclose(ref.end_state.q, target, rtol=0, atol=1e-7)
    held = generator.step(target)
    assert np.all(held.q_ref == ref.end_state.q[:, None])
    assert np.all(held.dq_ref == 0.0) and np.all(held.ddq_ref == 0.0)


@pytest.mark.parametrize("beyond", [0.0, 1.0])
def test_targets_at_or_beyond_the_limits_are_reached_at_the_limits(beyond: float) -> None:
    """Targets on the limits (or past them: clipped as a last guard) are followed with plain
    target plans, never a spurious range stop, and end just inside the range."""
    config = TrajectoryConfig(dynamics_factor=1.0)
    generator = TrajectoryGenerator(np.tile(Q_HOME, (2, 1)), config)
    target = np.stack([Q_MIN - beyond, Q_MAX + beyond])  # (2, J)
    for _ in range(40):
        ref = generator.step(target)
        assert np.all(ref.plan == Plan.TARGET)
    assert np.all(ref.reached)
    end = ref.end_state.q  # (2, J)
    assert np.all(end >= Q_MIN) and np.all(end <= Q_MAX)
    np.testing.assert_allclose(end, np.stack([Q_MIN, Q_MAX]), rtol=0, atol=2e-6)


def test_stop_brakes_to_rest_and_holds_until_resume() -> None:
    config = TrajectoryConfig()
    generator = TrajectoryGenerator(np.tile(Q_HOME, (B, 1)), config)
    far = np.tile(Q_HOME, (B, 1))
    far[:, [0, 4]] += 1.5  # (B, J)
    for _ in range(3):  # at full speed on joint 0 by now
        generator.step(far)
    assert np.all(np.abs(generator.state.dq[:, 0]) > 0.9 * config.dq_max[0])
    generator.stop(np.array([1, 3]))
    stop_time = np.max(config.dq_max / config.ddq_max + 2 * config.ddq_max / config.jerk_max)
    for _ in range(math.ceil(stop_time / config.policy_period_s)):
        ref = generator.step(far)
    assert list(ref.plan) == [Plan.TARGET, Plan.STOP, Plan.TARGET, Plan.STOP]
    assert np.all(ref.reached[[1, 3]])
    held = generator.step(far)
    assert np.all(held.dq_ref[[1, 3]] == 0.0)
    assert np.all(held.q_ref[[1, 3]] == ref.end_state.q[[1, 3], None])
    generator.resume(np.array([1, 3]))
    assert list(generator.step(far).plan) == [Plan.TARGET] * B


def test_reset_reanchors_at_rest_and_clears_stop() -> None:
    config = TrajectoryConfig()
    generator = TrajectoryGenerator(np.tile(Q_HOME, (B, 1)), config)
    target = np.tile(Q_HOME + 0.8, (B, 1))
    generator.step(target)
    generator.stop(np.array([2]))
    measured = Q_HOME[None] - 0.3  # (1, J)
    generator.reset(np.array([2]), measured)
    state = generator.state
    assert np.array_equal(state.q[2], measured[0]) and np.all(state.dq[2] == 0.0)
    assert not generator.stopping[2]
    ref = generator.step(target)
    step = np.abs(ref.q_ref[2, 0] - measured[0])  # (J,)
    assert np.all(step <= config.jerk_max * config.control_period_s**3 / 6 * (1 + FD_RTOL))


def test_non_finite_target_brakes_that_env_only_and_is_reported() -> None:
    config = TrajectoryConfig()
    generator = TrajectoryGenerator(np.tile(Q_HOME, (B, 1)), config)
    target = np.tile(Q_HOME + 0.5, (B, 1))
    generator.step(target)
    bad = target.copy()
    bad[1, 3] = np.nan
    ref = generator.step(bad)
    assert list(ref.plan) == [Plan.TARGET, Plan.STOP_INVALID_TARGET, Plan.TARGET, Plan.TARGET]
    assert ref.result[1] == -100 and np.all(ref.result[[0, 2, 3]] >= 0)
    assert np.all(np.isfinite(ref.q_ref))
    again = generator.step(target)
    assert np.all(again.plan == Plan.TARGET)


def test_plan_that_would_leave_the_range_brakes_instead() -> None:
    """Re-anchored moving towards q_max on joint 0 too fast to stop before it: no plan stays
    inside, so the reference brakes (the shortest overshoot) and reports it; once at rest
    outside, the next plans head straight back in."""
    config = TrajectoryConfig()
    generator = TrajectoryGenerator(np.tile(Q_HOME, (1, 1)), config)
    q = Q_HOME.copy()
    q[0] = Q_MAX[0] - 0.05
    dq = np.zeros(J)
    dq[0] = config.dq_max[0]
    generator.reset(np.array([0]), q[None], dq[None])
    target = Q_HOME[None]  # (1, J)
    ref = generator.step(target)
    assert ref.plan[0] == Plan.STOP_RANGE
    braking = config.dq_max[0] ** 2 / (2 * config.ddq_max[0])  # 0.17 rad > 0.05 rad of room
    assert ref.q_ref[0, :, 0].max() < q[0] + braking + 0.01
    plans = [generator.step(target).plan[0] for _ in range(30)]
    assert plans[-1] == Plan.TARGET and generator.state.q[0, 0] <= Q_MAX[0]


@pytest.mark.parametrize("control_rate_hz, samples", [(80.0, 8), (1000.0, 100), (10.0, 1)])
def test_samples_per_period_follow_the_control_rate(control_rate_hz: float, samples: int) -> None:
    config = TrajectoryConfig(control_rate_hz=control_rate_hz)
    assert config.samples_per_period == samples
    ref = TrajectoryGenerator(np.tile(Q_HOME, (B, 1)), config).step(np.tile(Q_HOME, (B, 1)))
    for array in (ref.q_ref, ref.dq_ref, ref.ddq_ref):
        assert array.shape == (B, samples, J) and array.dtype == np.float64
    assert ref.plan.shape == ref.result.shape == ref.reached.shape == (B,)


@pytest.mark.parametrize(
    "kwargs",
    [{"dynamics_factor": 0.0}, {"dynamics_factor": 1.5}, {"control_rate_hz": 75.0},
     {"policy_period_s": -0.1}, {"target_margin": 0.1}],
)  # fmt: skip
def test_invalid_config_fails_loudly(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        TrajectoryConfig(**kwargs)


def test_bad_shapes_and_non_finite_starts_fail_loudly() -> None:
    with pytest.raises(ValueError):
        TrajectoryGenerator(np.full((B, J), np.nan))
    generator = TrajectoryGenerator(np.tile(Q_HOME, (B, 1)))
    with pytest.raises(ValueError):
        generator.step(np.zeros((B, J - 1)))
    with pytest.raises(ValueError):
        generator.reset(np.array([0]), np.full((1, J), np.inf))
