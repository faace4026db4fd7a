"""The `fake` driver: the strict simulated FR3 (`hamnet.bridge.fake_fr3`) behind the bridge's
`Driver` interface, for tests and for `hamnet bridge --driver fake`.

The arm tracks every accepted reference sample exactly (no dynamics: the fake judges what is
commanded, as libfranka's reflexes do), so the measured velocity is the backward difference
of the executed samples and the measured torque is the impedance law's torque on the last
tick, tau = kp (q_ref - q) + kd (dq_ref - dq), clipped at the command's torque limits (no
gravity: libfranka compensates it). References execute when sent (virtual time), so a slow
machine never turns into a reflex; the command deadline is on the wall clock (`clock`) and
generous: it catches a bridge that stopped streaming while the arm moved. Lost connections
are simulated by `disconnect()`: the arm comes to rest, as the FR3 stops when its client goes;
`disconnect(reachable=False)` takes the robot off the network too, so that a reconnect fails
as libfranka's does until `reachable` is set again.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hamnet.bridge.driver import (
    CONNECTION_LOST,
    DEADLINE_MISSED,
    ImpedanceReference,
    RobotError,
    RobotReading,
)
from hamnet.bridge.fake_fr3 import FakeFR3, FakeFR3Config
from hamnet.fr3.limits import FR3, Q_HOME, FR3Limits
from hamnet.fr3.model import load_pinocchio, pinocchio_ee_placement
from hamnet.runtime.errors import ConfigError


@dataclass(frozen=True)
class FakeDriverConfig:
    """The fake robot's command deadline."""

    deadline_s: float = 1.0
    """Longest wall-clock gap between references while the arm moves, s; then the fake
    raises `command_deadline_missed` and stops (ten policy periods of the paper's 10 Hz)."""

    def __post_init__(self) -> None:
        if not self.deadline_s > 0.0:
            raise ConfigError(f"--deadline-s must be > 0 s, got {self.deadline_s}")


class FakeDriver:
    """A strict fake FR3 behind `Driver`, starting at rest at `q_start`."""

    def __init__(
        self,
        config: FakeDriverConfig | None = None,
        q_start: np.ndarray = Q_HOME,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.config = config if config is not None else FakeDriverConfig()
        self._clock = clock
        self.robot = FakeFR3(np.asarray(q_start, dtype=np.float64), FakeFR3Config())
        self._model, self._data = load_pinocchio()
        self._last = np.repeat(self.robot.q, 2, axis=0)  # (2, J): the last two executed, rad
        self._tau = np.zeros_like(self._last[0])  # (J,) N m, last tick's torque
        self._errors: list[RobotError] = []
        self._connected = False
        self.reachable = True
        """Whether `connect` finds the robot (False: a ConnectionError, as libfranka raises)."""
        self._stopped = False
        self._last_send = clock()
        self.sent = 0
        """References accepted for execution (whole or up to a reflex)."""
        self.refused = 0
        """References ignored because the arm was stopped, in error or disconnected."""

    @property
    def control_period_s(self) -> float:
        """The fake's control period, s (libfranka's 1 ms)."""
        return self.robot.config.control_period_s

    def connect(self) -> None:
        """Connect when the robot is `reachable` (else ConnectionError); the arm rests where
        it is."""
        if not self.reachable:
            raise ConnectionError("cannot reach the fake FR3: it is off the network")
        self._connected = True
        self._last_send = self._clock()

    def clock(self) -> float:
        """The wall clock (the fake executes references in virtual time when they arrive)."""
        return self._clock()

    def limits(self) -> FR3Limits:
        """The FR3's limits, which the fake enforces."""
        return self.robot.config.limits

    def read(self) -> RobotReading:
        """The executed state; ConnectionError when disconnected."""
        if not self._connected:
            raise ConnectionError("the fake FR3 is disconnected")
        q = self._last[1].copy()
        position, rotation = pinocchio_ee_placement(self._model, self._data, q)
        dq = (self._last[1] - self._last[0]) / self.control_period_s
        return RobotReading(q, dq, self._tau.copy(), position, rotation)

    def send(self, reference: ImpedanceReference) -> None:
        """Execute the references up to the first reflex (errors go to `poll_errors`)."""
        if not self._connected or self._stopped or self.robot.in_reflex[0]:
            self.refused += 1
            return
        q_ref = np.asarray(reference.q_ref, dtype=np.float64)  # (S, J)
        tau = self._torques(q_ref, reference)  # (S, J)
        before = int(self.robot.ticks[0])
        self.robot.command(q_ref, tau)
        executed = int(self.robot.ticks[0]) - before
        self.sent += 1
        self._last_send = self._clock()
        if executed:
            self._last = np.concatenate([self._last, q_ref[:executed]])[-2:]
            self._tau = tau[executed - 1]
        for names in self.robot.errors:
            if names:
                self._fail(*sorted(names))

    def stop(self) -> None:
        """The arm rests where it stands (the fake stops at once) until `reset`."""
        self._stopped = True
        self._last = np.repeat(self._last[1:], 2, axis=0)
        self._tau = np.zeros_like(self._tau)

    def poll_errors(self) -> list[RobotError]:
        """Errors since the last call; checks the command deadline first."""
        moving = np.any(self._last[1] != self._last[0])
        late = self._clock() - self._last_send > self.config.deadline_s
        if self._connected and not self._stopped and moving and late:
            self._errors.append(
                RobotError(
                    DEADLINE_MISSED,
                    f"no reference for over {self.config.deadline_s} s while moving",
                )
            )
            self.stop()
        errors, self._errors = self._errors, []
        return errors

    def reset(self) -> None:
        """Clear reflexes and the stop; the arm rests where it stands. ConnectionError when
        not connected (libfranka's recovery needs the link)."""
        if not self._connected:
            raise ConnectionError("the fake FR3 is not connected")
        self.stop()
        self.robot.recover(q=self._last[1:])
        self._stopped = False
        self._last_send = self._clock()

    def close(self) -> None:
        """Stop the arm and disconnect."""
        self.stop()
        self._connected = False

    def disconnect(self, reachable: bool = True) -> None:
        """Simulate a lost connection: the arm rests, `connection_lost` is reported;
        `reachable` False keeps the robot off the network until it is set True again."""
        self.reachable = reachable
        if self._connected:
            self.close()
            self._errors.append(RobotError(CONNECTION_LOST, "the fake FR3's link went down"))

    def _fail(self, *names: str) -> None:
        """Record the reflexes of the last block and stop."""
        self._errors.extend(RobotError(name, "reflex of the fake FR3") for name in names)
        self.stop()

    def _torques(self, q_ref: np.ndarray, reference: ImpedanceReference) -> np.ndarray:
        """Impedance torque on each tick, (S, J), N m, assuming exact tracking of the past.

        q_{k-1} and q_{k-2} are the executed samples before tick k; dq_ref and dq are their
        backward differences, so tau_k = kp (q_ref_k - q_{k-1}) + kd (q_ref_k - 2 q_{k-1} +
        q_{k-2}) / dt.
        """
        seq = np.concatenate([self._last, q_ref])  # (2 + S, J)
        step = seq[2:] - seq[1:-1]  # (S, J): q_ref_k - q_{k-1}
        change = step - (seq[1:-1] - seq[:-2])  # (S, J)
        tau = reference.kp * step + reference.kd * change / self.control_period_s
        limit = np.minimum(reference.tau_limit, FR3.tau_max)  # (J,)
        return np.clip(tau, -limit, limit)
