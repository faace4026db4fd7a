"""The `franky` driver: a real FR3 (or `franky-sim`) through libfranka, by franky's
client-side joint impedance tracking motion (PyPI `franky-control`, the `franky` extra).

franky runs the 1 kHz torque loop in C++ and reads, each cycle, the latest joint reference
and gains set from Python. The law is the sim's, the one the policy was trained with:
tau = kp (q_ref - q) - kd dq on top of the robot's own gravity compensation, so the
reference carries no velocity and franky's Coriolis compensation is off (with the samples'
velocity as feedforward the arm runs ahead of the trained one by up to 0.1 rad: `hamnet
bridge gap`, docs/bridge.md). A streamer thread plays each policy period's references on
the robot's clock (libfranka's state time, which on franky-sim can run slower than the wall
clock): sample i of a period is set i control periods after the period starts. A period
starts when the previous one ends, or when it arrives if the previous one has already ended
(the last sample was held meanwhile: a late command); a backlog of more than one period is
dropped, so latency cannot accumulate. The commanded torque limit is kept by bounding each
sample's distance from the measured position to tau_limit / kp (franky's tracking motion has
no per-command torque clamp; the damping term comes on top, and the robot's own limits stay
the hard ones).

Errors, polled by the streamer and returned by `poll_errors`: a libfranka control exception
(a reflex) by its message; the robot's clock standing still for `--franky.link-timeout-s`
of the wall clock (`connection_lost`: libfranka stops the robot on its side when its client
goes); no new period for `--franky.deadline-s` of the wall clock while moving
(`command_deadline_missed`). Any of them stops the motion; nothing is followed again until
`reset` (libfranka's error recovery).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from hamnet.bridge.driver import (
    CONNECTION_LOST,
    DEADLINE_MISSED,
    ImpedanceReference,
    RobotError,
    RobotReading,
)
from hamnet.fr3.limits import FR3, FR3Limits
from hamnet.fr3.model import load_pinocchio, pinocchio_ee_placement
from hamnet.runtime.errors import ConfigError

log = logging.getLogger(__name__)

CONTROL_PERIOD_S = 0.001
"""libfranka's control period, s."""
AT_REST = 1e-3
"""Joint speeds below this (rad/s) count as at rest for the command deadline."""


@dataclass(frozen=True)
class FrankyDriverConfig:
    """Where the robot is and how the stream to it is kept honest."""

    host: str = "172.16.0.2"
    """The robot's FCI address (Franka's default; franky-sim prints its loopback address)."""
    realtime: Literal["enforce", "ignore"] = "enforce"
    """libfranka's real-time check: enforce on the robot's real-time kernel; ignore for
    franky-sim or a machine without one."""
    deadline_s: float = 0.5
    """Longest gap between policy periods while the arm moves before the stream stops, s
    (five policy periods of the paper's 10 Hz; the last sample is held meanwhile)."""
    link_timeout_s: float = 0.1
    """The robot's clock standing still this long means the connection is lost, s."""
    gains_time_constant_s: float = 0.005
    """franky smooths gain changes with this time constant, s: short next to a policy
    period, so each period's gains settle within its first few milliseconds."""

    def __post_init__(self) -> None:
        for name in ("deadline_s", "link_timeout_s", "gains_time_constant_s"):
            if not getattr(self, name) > 0.0:
                raise ConfigError(f"--franky.{name.replace('_', '-')} must be > 0 s")


def import_franky() -> Any:
    """The franky module; ConfigError with the install line when the extra is missing."""
    try:
        import franky
    except ImportError as error:
        raise ConfigError(
            "the franky driver needs franky-control: pip install 'hamnet[franky]'"
        ) from error
    return franky


def play_sample(q_ref: np.ndarray, elapsed_s: float) -> np.ndarray:
    """The reference position `elapsed_s` into a period of samples q_ref (S, J) at
    libfranka's period: sample i from i periods on, the last one held once it is over."""
    return q_ref[min(int(elapsed_s / CONTROL_PERIOD_S), len(q_ref) - 1)]


def torque_bounded(
    q_ref: np.ndarray, q: np.ndarray, kp: np.ndarray, tau_limit: np.ndarray
) -> np.ndarray:
    """q_ref moved towards the measured q so that kp (q_ref - q) stays within tau_limit."""
    reach = np.where(kp > 0, tau_limit / np.maximum(kp, 1e-9), np.inf)
    return q + np.clip(q_ref - q, -reach, reach)


class FrankyDriver:
    """An FR3 through franky behind `Driver`; `connect` reaches the robot."""

    def __init__(
        self,
        config: FrankyDriverConfig | None = None,
        wall_clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.config = config if config is not None else FrankyDriverConfig()
        self.wall_clock = wall_clock
        self._franky = import_franky()
        self._model, self._data = load_pinocchio()
        self._robot: Any = None
        self._motion: Any = None
        self._lock = threading.Lock()
        self._period: ImpedanceReference | None = None  # guarded by _lock
        self._period_start = 0.0  # guarded by _lock
        self._last_send = wall_clock()
        self._errors: list[RobotError] = []  # guarded by _lock
        self._stopped = threading.Event()
        self._halt_lock = threading.Lock()
        self._streamer: threading.Thread | None = None
        self._robot_time = (-1.0, wall_clock())  # (robot's clock, s; wall clock when it changed)
        self.dropped = 0
        """Periods replaced before they started (a backlog of more than one)."""
        self.refused = 0
        """Periods ignored because the stream was stopped or the robot not connected."""

    @property
    def control_period_s(self) -> float:
        """libfranka's 1 ms."""
        return CONTROL_PERIOD_S

    def connect(self) -> None:
        """Connect to the robot at `--franky.host`; ConnectionError when it is not there."""
        franky = self._franky
        realtime = {
            "enforce": franky.RealtimeConfig.Enforce,
            "ignore": franky.RealtimeConfig.Ignore,
        }
        self.stop()
        self._robot = None  # the robot serves one client: the old connection goes first
        try:
            self._robot = franky.Robot(
                self.config.host, realtime_config=realtime[self.config.realtime]
            )
        except franky.Exception as error:  # NetworkException, IncompatibleVersionException, ...
            raise ConnectionError(
                f"cannot reach the robot at {self.config.host}: {error}"
            ) from error
        self._robot_time = (-1.0, self.wall_clock())
        self._stopped.clear()

    def clock(self) -> float:
        """The robot's clock (libfranka's state time), s."""
        return float(self._state().time.to_sec())

    def limits(self) -> FR3Limits:
        """The FR3's datasheet limits (libfranka does not report them)."""
        return FR3

    def read(self) -> RobotReading:
        """The robot's latest state; ConnectionError when its clock has stood still for the
        link timeout."""
        state = self._state()
        self._check_link(float(state.time.to_sec()))
        q = np.asarray(state.q, dtype=np.float64)
        position, rotation = pinocchio_ee_placement(self._model, self._data, q)
        return RobotReading(
            q,
            np.asarray(state.dq, dtype=np.float64),
            np.asarray(state.tau_J, dtype=np.float64),
            position,
            rotation,
        )

    def _state(self) -> Any:
        """libfranka's latest robot state; ConnectionError when there is no link."""
        if self._robot is None:
            raise ConnectionError("not connected to the robot")
        try:
            return self._robot.state
        except (self._franky.Exception, RuntimeError) as error:  # NetworkException, then
            raise ConnectionError(f"lost the robot: {error}") from error  # "Net Exception"

    def send(self, reference: ImpedanceReference) -> None:
        """Queue one policy period; the first after a connect or reset starts the motion."""
        if self._robot is None or self._stopped.is_set():
            self.refused += 1
            return
        self._last_send = self.wall_clock()
        now = self.clock()
        with self._lock:
            previous = self._period
            end = self._period_start + (len(previous.q_ref) * CONTROL_PERIOD_S if previous else 0.0)
            if previous is not None and end > now + len(reference.q_ref) * CONTROL_PERIOD_S:
                self.dropped += 1
                end = now
            self._period, self._period_start = reference, max(end, now)
        if self._motion is None:
            self._start(reference)
        else:
            self._motion.set_gains(self._franky.JointImpedanceGains(reference.kp, reference.kd))

    def stop(self) -> None:
        """Hold the measured position, end the motion; nothing is followed until `reset`."""
        self._stopped.set()
        streamer = self._streamer
        if streamer is not None and streamer is not threading.current_thread():
            streamer.join()
        self._halt()

    def poll_errors(self) -> list[RobotError]:
        """Errors the streamer found since the last call, oldest first."""
        with self._lock:
            errors, self._errors = self._errors, []
        return errors

    def reset(self) -> None:
        """libfranka's automatic error recovery; the arm holds where it stands.
        ConnectionError when the robot cannot be reached."""
        self.stop()
        if self._robot is None:
            raise ConnectionError("not connected to the robot")
        try:
            self._robot.recover_from_errors()
        except (self._franky.Exception, RuntimeError) as error:  # no link to recover over
            raise ConnectionError(f"cannot recover the robot: {error}") from error
        self._last_send = self.wall_clock()
        self._stopped.clear()

    def close(self) -> None:
        """Stop the arm and drop the connection."""
        self.stop()
        self._robot = None

    def _halt(self) -> None:
        """Set the hold reference (measured position, at rest) and end the motion; once."""
        with self._halt_lock:
            motion, self._motion = self._motion, None
            with self._lock:
                self._period = None
            if motion is None or self._robot is None:
                return
            try:
                motion.set_reference(self._franky.JointReference(q=np.asarray(self._state().q)))
                self._robot.stop()
                self._robot.join_motion(1.0)
            except (self._franky.Exception, ConnectionError) as error:  # the preemption, no link
                log.debug("ending the motion: %s", error)

    def _start(self, reference: ImpedanceReference) -> None:
        """Start franky's tracking motion at the measured position, then the streamer."""
        franky = self._franky
        self._motion = franky.JointImpedanceTrackingMotion(
            stiffness=reference.kp,
            damping=reference.kd,
            compensate_coriolis=False,
            gains_time_constant=self.config.gains_time_constant_s,
        )
        self._motion.set_reference(franky.JointReference(q=np.asarray(self._state().q)))
        self._robot.move(self._motion, asynchronous=True)
        self._streamer = threading.Thread(target=self._stream, name="franky-streamer", daemon=True)
        self._streamer.start()

    def _stream(self) -> None:
        """Set the current sample every control period until stopped or in error."""
        franky, robot, motion = self._franky, self._robot, self._motion
        while not self._stopped.is_set():
            with self._lock:
                period, start = self._period, self._period_start
            try:
                state = self._state()
            except ConnectionError as lost:
                state, error = None, RobotError(CONNECTION_LOST, str(lost))
            if state is not None:
                robot_time = float(state.time.to_sec())
                error = self._problem(robot, robot_time, np.asarray(state.dq), self.wall_clock())
            if error is not None:
                with self._lock:
                    self._errors.append(error)
                self._stopped.set()
                self._halt()
                return
            q = np.asarray(state.q, dtype=np.float64)
            q_ref = play_sample(period.q_ref, max(robot_time - start, 0.0))
            q_ref = torque_bounded(q_ref, q, period.kp, np.minimum(period.tau_limit, FR3.tau_max))
            motion.set_reference(franky.JointReference(q=q_ref))
            time.sleep(CONTROL_PERIOD_S)

    def _problem(
        self, robot: Any, robot_time: float, dq: np.ndarray, now: float
    ) -> RobotError | None:
        """Why the stream must stop now, or None."""
        try:
            robot.poll_motion()
        except self._franky.Exception as error:  # a ControlException: the robot's reflex
            return RobotError(_error_name(error), str(error))
        try:
            self._check_link(robot_time)
        except ConnectionError as error:
            return RobotError(CONNECTION_LOST, str(error))
        if now - self._last_send > self.config.deadline_s and np.abs(dq).max() > AT_REST:
            return RobotError(
                DEADLINE_MISSED, f"no reference for over {self.config.deadline_s} s while moving"
            )
        return None

    def _check_link(self, robot_time: float) -> None:
        """ConnectionError when the robot's clock has not moved for the link timeout."""
        last, since = self._robot_time
        now = self.wall_clock()
        if robot_time != last:
            self._robot_time = (robot_time, now)
        elif now - since > self.config.link_timeout_s:
            raise ConnectionError(f"the robot's clock stood still for {now - since:.2f} s")


def _error_name(error: Exception) -> str:
    """libfranka's error name from a control exception's message (its first reflex flag),
    else the exception's type."""
    text = str(error)
    for word in text.replace(",", " ").replace("[", " ").replace("]", " ").split():
        if word.endswith(("_reflex", "_discontinuity", "_violation", "_error")):
            return word
    return type(error).__name__
