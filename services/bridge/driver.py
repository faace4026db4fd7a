"""The one small interface every robot driver of the bridge implements.

The bridge core (`hamnet.bridge.core`) talks to a robot only through `Driver`, so the strict
fake (`hamnet.bridge.fake`), a libfranka client (franky) or Franka's own bindings are
interchangeable: each streams joint impedance references to the robot's 1 kHz loop and reports
what the robot measured and which errors it raised. Errors are polled as typed values rather
than raised, because they happen on the robot's clock, not on the caller's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from hamnet.fr3.limits import FR3Limits

CONNECTION_LOST = "connection_lost"
"""The driver lost its connection to the robot (the robot stops on its own side)."""
DEADLINE_MISSED = "command_deadline_missed"
"""No new reference within the driver's deadline while the arm was moving."""
COMMAND_REJECTED = "command_rejected"
"""The bridge refused a command before it reached the robot (non-finite, out of limits)."""
STOP_REQUESTED = "stop_requested"
"""An operator stopped the stream (the bridge's `stop` query)."""


@dataclass(frozen=True)
class RobotReading:
    """What the robot measured at one instant."""

    q: np.ndarray
    """(J,) joint positions, rad."""
    dq: np.ndarray
    """(J,) joint velocities, rad/s."""
    tau: np.ndarray
    """(J,) measured joint torques, N m."""
    ee_position: np.ndarray
    """(3,) end-effector position in the world, m."""
    ee_rotation: np.ndarray
    """(3, 3) end-effector rotation matrix in the world."""


@dataclass(frozen=True)
class ImpedanceReference:
    """One policy period of joint impedance references, streamed at the driver's period."""

    q_ref: np.ndarray
    """(S, J) joint position references, one per control period, rad."""
    kp: np.ndarray
    """(J,) joint stiffness, N m/rad."""
    kd: np.ndarray
    """(J,) joint damping, N m s/rad."""
    tau_limit: np.ndarray
    """(J,) torque limits of the executor's hard clip, N m."""


@dataclass(frozen=True)
class RobotError:
    """An error the robot (or the bridge on its behalf) raised; the stream stops on it."""

    name: str
    """libfranka's error name (e.g. `joint_motion_generator_velocity_discontinuity`) or one of
    CONNECTION_LOST, DEADLINE_MISSED, COMMAND_REJECTED, STOP_REQUESTED."""
    reason: str = ""
    """Human-readable detail."""


class Driver(Protocol):
    """A robot behind the bridge: connect, read, stream references, stop, report, reset."""

    @property
    def control_period_s(self) -> float:
        """Period of the robot's control loop, s (1 ms for libfranka)."""
        ...

    def connect(self) -> None:
        """Connect to the robot; raises ConnectionError when it cannot."""
        ...

    def clock(self) -> float:
        """The robot's clock, s: the bridge paces its states by it (a simulated robot may
        run slower than the wall clock; a real one does not)."""
        ...

    def limits(self) -> FR3Limits:
        """The robot's joint limits."""
        ...

    def read(self) -> RobotReading:
        """The robot's latest measured state."""
        ...

    def send(self, reference: ImpedanceReference) -> None:
        """Stream one policy period of references (errors come back through `poll_errors`)."""
        ...

    def stop(self) -> None:
        """Bring the arm to rest and hold it there; no reference is followed until `reset`."""
        ...

    def poll_errors(self) -> list[RobotError]:
        """Errors raised since the last call, oldest first."""
        ...

    def reset(self) -> None:
        """Clear the robot's errors (libfranka's automatic error recovery); the arm holds
        where it stands."""
        ...

    def close(self) -> None:
        """Stop the arm and disconnect."""
        ...
