"""Commands the sim makes itself: holding the arm where it is.

Used by the shell in free-running mode before the first SafeCommand arrives, by the sim
benchmark, and by tests that stand in for the safety filter. The gains are moderate: the
middle of the impedance range kp in [10, 200] (see `robot.py`), critically damped-ish
(rho = 1, kd = rho*sqrt(kp)), clipped at the FR3's torque limits.
"""

from __future__ import annotations

import numpy as np

from hamnet.fr3.limits import FR3
from hamnet.sim.env import Command

HOLD_KP = 100.0
"""Stiffness of a hold, N m/rad."""
HOLD_RHO = 1.0
"""Damping ratio of a hold: kd = rho*sqrt(kp), N m s/rad."""


def hold_command(
    q: np.ndarray, control_samples: int, kp: float = HOLD_KP, rho: float = HOLD_RHO
) -> Command:
    """Track the joint positions `q` for one policy period.

    Args:
        q: (B, J) joint positions to hold, rad.
        control_samples: S, reference samples per policy period.
        kp: stiffness, N m/rad; rho: damping ratio.
    Returns:
        A Command with q_ref (B, S, J) = q, kp, kd (B, J) and tau_limit (B, J) = FR3.tau_max.
    """
    q = np.asarray(q, dtype=np.float64)  # (B, J)
    b, j = q.shape
    return Command(
        q_ref=np.repeat(q[:, None, :], control_samples, axis=1),  # (B, S, J)
        kp=np.full((b, j), kp),
        kd=np.full((b, j), rho * np.sqrt(kp)),
        tau_limit=np.tile(FR3.tau_max, (b, 1)),
    )
