"""Termination: success needs both thresholds, dropping leaves the workspace box, timeout
truncates but does not terminate, and the reason codes."""

from __future__ import annotations

import math

import numpy as np

from hamnet.sim import quaternion
from hamnet.sim.task_config import TASK_PRESETS, TaskConfig
from hamnet.sim.termination import (
    REASON_NAMES,
    Reason,
    is_dropped,
    is_success,
    is_timeout,
    orientation_error,
    position_error,
    termination,
    workspace_bounds,
)

PAPER = TASK_PRESETS["paper"]
CODE = TASK_PRESETS["code"]
Z = np.array([0.0, 0.0, 1.0])
B = 4


def yaw(angle: float) -> np.ndarray:
    return quaternion.from_axis_angle(Z, np.asarray(angle))


def goal() -> tuple[np.ndarray, np.ndarray]:
    pos = np.tile([0.6, 0.0, 0.25], (B, 1))  # (B, 3)
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (B, 1))  # (B, 4)
    return pos, quat


def table() -> tuple[np.ndarray, np.ndarray]:
    """A 0.4 x 0.6 x 0.2 table centred at (0.6, 0, 0.1): top at z = 0.2."""
    return np.tile([0.6, 0.0, 0.1], (B, 1)), np.tile([0.2, 0.3, 0.1], (B, 1))


def test_errors_by_hand() -> None:
    goal_pos, goal_quat = goal()
    pos = goal_pos + np.array([[0.03, 0.04, 0.0], [0, 0, 0], [0, 0, 0.1], [0, 0, 0]])
    quat = np.stack([goal_quat[0], yaw(0.3), yaw(-0.3), yaw(math.pi)])
    np.testing.assert_allclose(position_error(pos, goal_pos), [0.05, 0.0, 0.1, 0.0], atol=1e-12)
    angle = orientation_error(quat, goal_quat)
    np.testing.assert_allclose(angle, [0.0, 0.3, 0.3, math.pi], atol=1e-6)


def test_success_only_when_both_thresholds_hold() -> None:
    """B = 4: both within (0.05 m, 0.05 rad); position off (0.15 m); orientation off
    (0.2 rad); 0.1 m up to rounding with 0.09 rad."""
    goal_pos, goal_quat = goal()
    pos = goal_pos + np.array([[0.05, 0, 0], [0.15, 0, 0], [0, 0.05, 0], [0, 0, 0.1]])
    quat = np.stack([yaw(0.05), yaw(0.05), yaw(0.2), yaw(0.09)])
    np.testing.assert_array_equal(
        is_success(pos, quat, goal_pos, goal_quat, PAPER), [True, False, False, True]
    )
    # Both thresholds are inclusive: exactly 0.1 m away (exact in floating point) succeeds.
    origin = np.zeros((1, 3))
    assert is_success(np.array([[0.1, 0.0, 0.0]]), goal_quat[:1], origin, goal_quat[:1], PAPER)


def test_code_threshold_is_tighter_than_the_paper() -> None:
    """0.07 m from the goal: a success with the paper's 0.1 m, not with the code's 0.05 m."""
    goal_pos, goal_quat = goal()
    pos = goal_pos + np.array([0.07, 0.0, 0.0])
    assert is_success(pos, goal_quat, goal_pos, goal_quat, PAPER).all()
    assert not is_success(pos, goal_quat, goal_pos, goal_quat, CODE).any()


def test_workspace_bounds_by_hand() -> None:
    """xy: table +- 0.3 m margin; z: 0.1 m below the 0.2 m top to 0.5 m above it."""
    lo, hi = workspace_bounds(*table(), PAPER)
    np.testing.assert_allclose(lo, np.tile([0.1, -0.6, 0.1], (B, 1)))
    np.testing.assert_allclose(hi, np.tile([1.1, 0.6, 0.7], (B, 1)))


def test_dropped_when_the_centre_leaves_the_workspace() -> None:
    """B = 4: on the table; fallen below the top by more than 0.1 m; past the xy margin;
    just over the table's edge but still above the drop line (not yet dropped)."""
    lo, hi = workspace_bounds(*table(), PAPER)
    pos = np.array([[0.6, 0, 0.25], [0.85, 0, 0.05], [0.6, 0.65, 0.25], [0.85, 0, 0.15]])
    np.testing.assert_array_equal(is_dropped(pos, lo, hi), [False, True, True, False])


def test_timeout_at_the_configured_step() -> None:
    steps = np.array([1, 299, 300, 301])
    np.testing.assert_array_equal(is_timeout(steps, PAPER), [False, False, True, True])
    short = TaskConfig(timeout=10)
    np.testing.assert_array_equal(is_timeout(steps, short), [False, True, True, True])


def test_timeout_truncates_and_success_or_drop_terminates() -> None:
    """B = 4 at various steps: running (step 10); timed out (step 300) -> truncated only;
    success on the timeout step -> terminated, not truncated; dropped (step 5) ->
    terminated without success. A timeout flagged as terminated would stop the trainer
    from bootstrapping a state the policy could still have finished from."""
    goal_pos, goal_quat = goal()
    workspace = workspace_bounds(*table(), PAPER)
    pos = goal_pos + np.array([[0.2, 0, 0], [0.2, 0, 0], [0.0, 0, 0], [0.0, 0, -0.3]])
    steps = np.array([10, 300, 300, 5])
    result = termination(pos, goal_quat, goal_pos, goal_quat, workspace, steps, PAPER)
    np.testing.assert_array_equal(result.terminated, [False, False, True, True])
    np.testing.assert_array_equal(result.truncated, [False, True, False, False])
    np.testing.assert_array_equal(result.success, [False, False, True, False])
    np.testing.assert_array_equal(result.done, [False, True, True, True])
    assert result.reason.dtype == np.int8
    np.testing.assert_array_equal(
        result.reason, [Reason.RUNNING, Reason.TIMEOUT, Reason.SUCCESS, Reason.DROPPED]
    )


def test_reason_names_follow_the_codes() -> None:
    assert REASON_NAMES == ("running", "success", "dropped", "timeout")
    assert [REASON_NAMES[int(r)] for r in Reason] == list(REASON_NAMES)


def test_default_success_is_the_authors_training_configuration() -> None:
    """The reported success rates use 0.05 m and 0.1 rad (rss_train.yaml task.goal_radius,
    goal_angle); the paper's 0.1 m stays the "paper" preset. 0.07 m away fails by default."""
    assert (TaskConfig().success_radius, TaskConfig().success_angle) == (0.05, 0.1)
    assert PAPER.success_radius == 0.1
    goal_pos, goal_quat = goal()
    pos = goal_pos + np.array([0.07, 0.0, 0.0])
    assert not is_success(pos, goal_quat, goal_pos, goal_quat, TaskConfig()).any()
