"""The strict fake FR3 (hamnet.bridge.fake_fr3): it accepts what stage 6 generates, tick by tick
at 1 kHz for thousands of ticks, and rejects hand-made bad references with the reflex libfranka
would name.

Bad references are built from a chosen acceleration per tick, integrated the way backward
differences undo it (v_k = v_{k-1} + a_k dt, q_k = q_{k-1} + v_k dt), so each one breaks exactly
the limit it is meant to break and no other.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hamnet.bridge.fake_fr3 import FakeFR3, FakeFR3Config, ReflexError
from hamnet.fr3.limits import FR3, Q_HOME
from hamnet.fr3.reflexes import (
    ACCELERATION_DISCONTINUITY,
    NON_FINITE,
    POSITION_LIMITS,
    START_POSE_INVALID,
    TORQUE_DISCONTINUITY,
    TORQUE_RANGE,
    VELOCITY_DISCONTINUITY,
    VELOCITY_LIMITS,
)
from hamnet.safety.references import Plan, TrajectoryConfig
from hamnet.safety.ruckig_references import TrajectoryGenerator

DT = 1e-3
J = 7
Q_MIN, Q_MAX = np.asarray(FR3.q_min), np.asarray(FR3.q_max)
KHZ = TrajectoryConfig(control_rate_hz=1000.0)
"""Stage 6 at libfranka's rate: S = 100 samples per 0.1 s policy period."""


def from_accelerations(q0: np.ndarray, acceleration: np.ndarray) -> np.ndarray:
    """Positions whose backward differences are exactly the given accelerations from rest.

    Args:
        q0: start, (J,), rad.
        acceleration: per tick, (T, J), rad/s^2.
    Returns:
        (T, J), rad.
    """
    velocity = np.cumsum(acceleration, axis=0) * DT  # (T, J), rad/s
    return q0 + np.cumsum(velocity, axis=0) * DT


def ramp(peak: float, ticks: int, slope: float = 4.0) -> np.ndarray:
    """Acceleration of joint 0 rising by `slope` per tick (jerk 4000 rad/s^3) to `peak`, then
    held, (ticks, J), rad/s^2."""
    acceleration = np.zeros((ticks, J))
    acceleration[:, 0] = np.minimum(slope * np.arange(1, ticks + 1), peak)
    return acceleration


def test_a_smooth_move_within_limits_is_accepted() -> None:
    """Joint 0 accelerates at 8 rad/s^2 to 2.4 rad/s and brakes back to rest, jerk 4000."""
    robot = FakeFR3(Q_HOME)
    acceleration = np.zeros((600, J))
    knots = ([0, 2, 298, 302, 598, 600], [0.0, 8.0, 8.0, -8.0, -8.0, 0.0])
    acceleration[:, 0] = np.interp(np.arange(1, 601), *knots)
    q = from_accelerations(Q_HOME, acceleration)  # (600, J)
    assert robot.command(q)
    assert robot.ticks[0] == 600 and robot.errors == (frozenset(),)
    assert robot.command(np.tile(q[-1], (5, 1)))  # at rest: holding is accepted


def test_position_jump_is_a_velocity_violation_and_both_discontinuities() -> None:
    """A 10 mrad step in the middle of a hold: above dq_max * dt (2.6 mrad), so the velocity,
    its jump (acceleration) and the acceleration's jump (jerk) all break their limits; the ticks
    before the jump are executed and the robot refuses everything after it."""
    robot = FakeFR3(Q_HOME)
    q = np.tile(Q_HOME, (20, 1))  # (20, J)
    q[10:, 3] += 0.01
    assert not robot.command(q)
    assert robot.errors[0] == {VELOCITY_LIMITS, VELOCITY_DISCONTINUITY, ACCELERATION_DISCONTINUITY}
    assert robot.ticks[0] == 10 and robot.reflex_tick[0] == 10
    assert not robot.command(np.tile(Q_HOME, (5, 1)))
    assert robot.refused[0] == 1 and robot.ticks[0] == 10


@pytest.mark.parametrize("fraction, over_speed", [(0.99, False), (1.01, True)])
def test_jump_threshold_is_dq_max_times_dt(fraction: float, over_speed: bool) -> None:
    robot = FakeFR3(Q_HOME)
    q = np.tile(Q_HOME, (4, 1))  # (4, J)
    q[2:, 0] += fraction * FR3.dq_max[0] * DT
    robot.command(q[:2])
    robot.command(q[2:])
    assert (VELOCITY_LIMITS in robot.errors[0]) is over_speed
    assert VELOCITY_DISCONTINUITY in robot.errors[0]  # from rest, any such jump is one
    assert START_POSE_INVALID not in robot.errors[0]


def test_over_speed_reached_smoothly_is_only_a_velocity_violation() -> None:
    """Accelerating at 8 rad/s^2 (jerk 4000) until joint 0 passes 1.02 dq_max."""
    start = Q_HOME.copy()
    start[0] = -2.5
    robot = FakeFR3(start)
    q = from_accelerations(start, ramp(8.0, 400))  # (400, J)
    speed = np.diff(np.vstack([start, q]), axis=0)[:, 0] / DT  # (400,)
    first_over = int(np.argmax(speed > FR3.dq_max[0]))
    assert speed.max() > 1.02 * FR3.dq_max[0] and first_over > 0
    assert not robot.command(q)
    assert robot.errors[0] == {VELOCITY_LIMITS}
    assert robot.reflex_tick[0] == first_over


def test_over_acceleration_is_only_a_velocity_discontinuity() -> None:
    robot = FakeFR3(Q_HOME)
    assert not robot.command(from_accelerations(Q_HOME, ramp(12.0, 10)))
    assert robot.errors[0] == {VELOCITY_DISCONTINUITY}
    assert robot.reflex_tick[0] == 2  # accelerations 4, 8, 12: the third tick


def test_over_jerk_is_only_an_acceleration_discontinuity() -> None:
    robot = FakeFR3(Q_HOME)
    acceleration = ramp(6.0, 10, slope=6.0)  # 0 to 6 rad/s^2 in one tick: 6000 rad/s^3
    assert not robot.command(from_accelerations(Q_HOME, acceleration))
    assert robot.errors[0] == {ACCELERATION_DISCONTINUITY}
    assert robot.reflex_tick[0] == 0


def test_creeping_past_a_limit_is_only_a_position_violation() -> None:
    start = Q_HOME.copy()
    start[3] = Q_MAX[3] - 1e-4
    robot = FakeFR3(start)
    acceleration = np.zeros((50, J))
    acceleration[:, 3] = 1.0
    assert not robot.command(from_accelerations(start, acceleration))
    assert robot.errors[0] == {POSITION_LIMITS}
    assert np.all(robot.q[0] <= Q_MAX)


def test_first_command_away_from_the_start_is_an_invalid_start_pose() -> None:
    robot = FakeFR3(Q_HOME)
    assert not robot.command((Q_HOME + 0.01)[None])
    assert START_POSE_INVALID in robot.errors[0] and VELOCITY_LIMITS in robot.errors[0]


def test_non_finite_command_is_rejected() -> None:
    robot = FakeFR3(Q_HOME)
    q = np.tile(Q_HOME, (3, 1))
    q[1, 2] = np.nan
    assert not robot.command(q)
    assert robot.errors[0] == {NON_FINITE} and robot.ticks[0] == 1


def test_torque_range_and_rate() -> None:
    """Torque on joint 6 (tau_max 12 N m) ramped at 900 N m/s: accepted up to 12 N m, the
    tick past it is a range violation; a 2 N m step (2000 N m/s) is a torque discontinuity."""
    hold = np.tile(Q_HOME, (20, 1))  # (20, J)
    tau = np.zeros((20, J))
    tau[:, 6] = 0.9 * np.arange(1, 21)  # N m
    robot = FakeFR3(Q_HOME)
    assert not robot.command(hold, tau)
    assert robot.errors[0] == {TORQUE_RANGE} and robot.reflex_tick[0] == 13
    robot = FakeFR3(Q_HOME)
    tau = np.zeros((20, J))
    tau[10:, 0] = 2.0
    assert not robot.command(hold, tau)
    assert robot.errors[0] == {TORQUE_DISCONTINUITY} and robot.reflex_tick[0] == 10


def test_recover_clears_the_reflex_and_restarts_from_rest() -> None:
    robot = FakeFR3(Q_HOME)
    q = np.tile(Q_HOME, (4, 1))
    q[2:, 0] += 0.01
    robot.command(q)
    assert robot.in_reflex[0]
    robot.recover()
    assert not robot.in_reflex[0] and robot.reflex_tick[0] == -1
    assert robot.command(np.tile(Q_HOME, (3, 1)))  # held where it stopped
    robot.command(q)
    robot.recover(q=(Q_HOME + 0.01)[None])  # measured elsewhere after the reflex
    assert robot.command(np.tile(Q_HOME + 0.01, (3, 1)))


def test_batch_reflexes_only_the_offending_robot_and_can_raise() -> None:
    start = np.tile(Q_HOME, (3, 1))  # (3, J)
    q = np.tile(Q_HOME, (3, 5, 1))  # (3, 5, J)
    q[1, 3:, 0] += 0.01
    robot = FakeFR3(start)
    assert list(robot.command(q)) == [True, False, True]
    assert robot.errors[0] == robot.errors[2] == frozenset()
    assert list(robot.ticks) == [5, 3, 5]
    strict = FakeFR3(start, FakeFR3Config(raise_on_reflex=True))
    with pytest.raises(ReflexError) as caught:
        strict.command(q)
    assert set(caught.value.errors) == {1}


def test_bad_command_shapes_fail_loudly() -> None:
    with pytest.raises(ValueError):
        FakeFR3(np.tile(Q_HOME, (2, 1))).command(np.zeros((3, 5, J)))
    with pytest.raises(ValueError):
        FakeFR3(Q_HOME).command(np.zeros((5, J - 1)))


def drive(
    generator: TrajectoryGenerator,
    robot: FakeFR3,
    periods: int,
    rng: np.random.Generator,
) -> None:
    """Random targets (some at the limits, some non-finite) and watchdog stops through stage 6
    into the fake, one policy period of 100 ticks at a time; fails at the first reflex."""
    B = generator.num_envs
    for period in range(periods):
        kind = rng.integers(4)
        target = rng.uniform(Q_MIN, Q_MAX, size=(B, J))  # (B, J)
        if kind == 1:
            target = np.where(rng.random((B, J)) < 0.5, Q_MIN, Q_MAX)
        elif kind == 2:
            target[rng.integers(B), rng.integers(J)] = np.nan
        elif kind == 3:
            generator.stop(rng.random(B) < 0.3)
            generator.resume(rng.random(B) < 0.5)
        references = generator.step(target)
        accepted = robot.command(references.q_ref)
        assert np.all(accepted), (period, robot.errors, references.plan)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dynamics_factor=st.sampled_from([0.5, 1.0]))
def test_generated_references_never_trigger_a_reflex(seed: int, dynamics_factor: float) -> None:
    """3000 ticks per robot at 1 kHz, also at the full FR3 limits (dynamics factor 1)."""
    config = TrajectoryConfig(dynamics_factor=dynamics_factor, control_rate_hz=1000.0)
    rng = np.random.default_rng(seed)
    start = rng.uniform(Q_MIN, Q_MAX, size=(4, J))  # (4, J)
    generator = TrajectoryGenerator(start, config)
    robot = FakeFR3(start)
    drive(generator, robot, periods=30, rng=rng)
    assert np.all(robot.ticks == 3000) and not robot.in_reflex.any()


def test_soak_ten_thousand_ticks_per_robot_without_a_reflex() -> None:
    rng = np.random.default_rng(7)
    start = np.tile(Q_HOME, (8, 1))  # (8, J)
    generator = TrajectoryGenerator(start, KHZ)
    robot = FakeFR3(start)
    drive(generator, robot, periods=100, rng=rng)
    assert np.all(robot.ticks == 10_000) and robot.refused.sum() == 0


def test_episode_reset_after_recover_continues_without_a_reflex() -> None:
    """A reflex, then recover and re-anchor stage 6 at the robot's position: the new motion
    starts from rest where the robot stands, which the fake accepts."""
    generator = TrajectoryGenerator(Q_HOME[None], KHZ)
    robot = FakeFR3(Q_HOME)
    robot.command(generator.step((Q_HOME + 0.5)[None]).q_ref[0])
    robot.command((robot.q[0] + 0.05)[None])  # a jump: reflex
    assert robot.in_reflex[0]
    robot.recover()
    generator.reset(np.array([0]), robot.q)
    for _ in range(20):
        references = generator.step((Q_HOME - 0.5)[None])
        assert robot.command(references.q_ref[0]) and references.plan[0] == Plan.TARGET
