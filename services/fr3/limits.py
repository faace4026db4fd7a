"""Facts about the Franka Research 3 that every service shares: joints, limits, home pose,
the width of the policy's action.

The limits are Franka's FR3 control-parameter table; the model file (`hamnet.fr3.model`)
holds the same joint ranges and torque limits (tests/fr3/test_model.py checks). The sim, the
safety filter, the policy and the real-robot bridge import these instead of restating them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

JOINT_NAMES = tuple(f"fr3_joint{i}" for i in range(1, 8))
"""Joint names in the model, in the order of every joint-space array (J = 7)."""

NUM_JOINTS = len(JOINT_NAMES)
"""J: joints of the arm."""

ACTION_DIM = 3 * NUM_JOINTS
"""Width of the policy's raw action: [joint residual | kp | damping ratio], J columns each."""


def _frozen(values: list[float]) -> np.ndarray:
    array = np.array(values, dtype=np.float64)
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class FR3Limits:
    """Franka's FR3 control-parameter table (docs: Facts about the dependencies)."""

    q_min: np.ndarray = field(
        default_factory=lambda: _frozen(
            [-2.9007, -1.8361, -2.9007, -3.0770, -2.8763, 0.4398, -3.0508]
        )
    )
    """Lower joint position limits, (J,), rad."""
    q_max: np.ndarray = field(
        default_factory=lambda: _frozen([2.9007, 1.8361, 2.9007, -0.1169, 2.8763, 4.6216, 3.0508])
    )
    """Upper joint position limits, (J,), rad."""
    dq_max: np.ndarray = field(
        default_factory=lambda: _frozen([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26])
    )
    """Joint speed limits, (J,), rad/s."""
    ddq_max: np.ndarray = field(default_factory=lambda: _frozen([10.0] * 7))
    """Joint acceleration limits, (J,), rad/s^2."""
    jerk_max: np.ndarray = field(default_factory=lambda: _frozen([5000.0] * 7))
    """Joint jerk limits, (J,), rad/s^3."""
    tau_max: np.ndarray = field(default_factory=lambda: _frozen([87.0] * 4 + [12.0] * 3))
    """Joint torque limits, (J,), N m (symmetric: the model's ctrlrange is +-tau_max)."""
    dtau_max: np.ndarray = field(default_factory=lambda: _frozen([1000.0] * 7))
    """Joint torque rate limits, (J,), N m/s."""
    ee_speed_max: float = 3.0
    """End-effector translational speed limit, m/s."""
    ee_acc_max: float = 9.0
    """End-effector translational acceleration limit, m/s^2."""
    ee_jerk_max: float = 4500.0
    """End-effector translational jerk limit, m/s^3."""
    ee_ang_speed_max: float = 2.5
    """End-effector angular speed limit, rad/s."""
    ee_ang_acc_max: float = 17.0
    """End-effector angular acceleration limit, rad/s^2."""
    ee_ang_jerk_max: float = 8500.0
    """End-effector angular jerk limit, rad/s^3."""


FR3 = FR3Limits()
"""The FR3's limits; arrays are read-only."""

Q_HOME = _frozen([0.0, -0.2, 0.0, -2.0, 0.0, 1.8, np.pi / 4])
"""Home configuration, (J,), rad: paddle face down, about (0.50, 0.00, 0.455) m, above a
table in front of the robot; q6 = q2 - q4 keeps the paddle level, q7 = pi/4 aligns its
edges with the world axes."""


