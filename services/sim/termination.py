"""When an episode ends (paper, line 245), batched over B environments, pure numpy.

An episode ends when (1) the object reaches the goal, (2) the object is dropped from the
workspace, or (3) it reaches the timeout. (1) and (2) are true terminal states: the
trainer must not bootstrap past them. (3) is a time limit, not part of the task's state,
so it only truncates and the trainer bootstraps from the last state. Consumes object and
goal poses, per-environment workspace bounds and episode step counts; produces a
`Termination` with a reason code per environment for logging.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from hamnet.sim import quaternion
from hamnet.sim.task_config import TaskConfig


class Reason(IntEnum):
    """Why an environment's episode ended on this step; one wins when several hold."""

    RUNNING = 0
    """The episode goes on."""
    SUCCESS = 1
    """The object is at the goal (terminated); wins over the others."""
    DROPPED = 2
    """The object left the workspace (terminated)."""
    TIMEOUT = 3
    """The episode reached `TaskConfig.timeout` (truncated)."""


REASON_NAMES = tuple(reason.name.lower() for reason in Reason)
"""Names of the reason codes, indexed by code: running, success, dropped, timeout."""


@dataclass(frozen=True)
class Termination:
    """The end-of-episode flags of one step."""

    terminated: np.ndarray
    """(B,) bool: success or dropped; the next state is terminal (no bootstrap)."""
    truncated: np.ndarray
    """(B,) bool: timeout without termination; bootstrap from the next state."""
    success: np.ndarray
    """(B,) bool: the object is within both success thresholds of the goal."""
    reason: np.ndarray
    """(B,) int8 `Reason` code."""

    @property
    def done(self) -> np.ndarray:
        """(B,) bool: the environment must be reset."""
        return self.terminated | self.truncated


def position_error(pos: np.ndarray, goal_pos: np.ndarray) -> np.ndarray:
    """Distance (B,) between object and goal positions (B, 3), m."""
    return np.linalg.norm(pos - goal_pos, axis=-1)


def orientation_error(quat: np.ndarray, goal_quat: np.ndarray) -> np.ndarray:
    """Angle (B,) in [0, pi] of the rotation between object and goal orientations (B, 4) wxyz,
    rad."""
    return quaternion.angle_between(quat, goal_quat)


def is_success(
    pos: np.ndarray,
    quat: np.ndarray,
    goal_pos: np.ndarray,
    goal_quat: np.ndarray,
    config: TaskConfig,
) -> np.ndarray:
    """(B,) bool: position error <= success_radius and orientation error <= success_angle."""
    near = position_error(pos, goal_pos) <= config.success_radius
    aligned = orientation_error(quat, goal_quat) <= config.success_angle
    return near & aligned


def workspace_bounds(
    table_centre: np.ndarray, table_half_extent: np.ndarray, config: TaskConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Box the object's centre must stay in, per environment (computed once per scene).

    Args:
        table_centre: (B, 3) centre of the axis-aligned table cuboid, m
            (`SceneBatch.centre[:, TABLE]`).
        table_half_extent: (B, 3) its half extents, m (`SceneBatch.half_extent[:, TABLE]`).
        config: margins.
    Returns:
        lo, hi: (B, 3) each, m. xy: the table grown by workspace_margin_xy; z: from
        drop_depth below the table top to workspace_height above it.
    """
    table_top = table_centre[:, 2] + table_half_extent[:, 2]  # (B,), m
    margin = np.array([config.workspace_margin_xy, config.workspace_margin_xy])
    lo_xy = table_centre[:, :2] - table_half_extent[:, :2] - margin  # (B, 2)
    hi_xy = table_centre[:, :2] + table_half_extent[:, :2] + margin  # (B, 2)
    lo = np.concatenate([lo_xy, (table_top - config.drop_depth)[:, None]], axis=-1)
    hi = np.concatenate([hi_xy, (table_top + config.workspace_height)[:, None]], axis=-1)
    return lo, hi


def is_dropped(pos: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(B,) bool: the object's centre pos (B, 3) is outside [lo, hi] (B, 3) on some axis."""
    return np.any((pos < lo) | (pos > hi), axis=-1)


def is_timeout(episode_step: np.ndarray, config: TaskConfig) -> np.ndarray:
    """(B,) bool: `episode_step` (B,), the policy steps taken including this one, reached
    the timeout; an episode holds at most `config.timeout` transitions."""
    return episode_step >= config.timeout


def termination(
    pos: np.ndarray,
    quat: np.ndarray,
    goal_pos: np.ndarray,
    goal_quat: np.ndarray,
    workspace: tuple[np.ndarray, np.ndarray],
    episode_step: np.ndarray,
    config: TaskConfig | None = None,
) -> Termination:
    """End-of-episode flags after one policy step.

    Args:
        pos, quat: (B, 3) m and (B, 4) wxyz, the object's pose after the step.
        goal_pos, goal_quat: (B, 3) m and (B, 4) wxyz, its goal.
        workspace: (lo, hi), (B, 3) each, from `workspace_bounds`.
        episode_step: (B,) int, policy steps taken in the episode including this one.
        config: thresholds; the default is the paper's.
    Returns:
        The flags. A success on the timeout step terminates (it is not truncated).
    """
    config = config if config is not None else TaskConfig()
    success = is_success(pos, quat, goal_pos, goal_quat, config)  # (B,)
    dropped = is_dropped(pos, *workspace)  # (B,)
    timeout = is_timeout(episode_step, config)  # (B,)
    terminated = success | dropped
    codes = [int(Reason.SUCCESS), int(Reason.DROPPED), int(Reason.TIMEOUT)]
    reason = np.select([success, dropped, timeout], codes, int(Reason.RUNNING))  # (B,)
    return Termination(
        terminated=terminated,
        truncated=timeout & ~terminated,
        success=success,
        reason=reason.astype(np.int8),
    )
