"""The bridge's core, without Zenoh: safe commands in, driver calls out, robot state and
error events back, and the rule that an error stops the command stream until a reset.

Every command is checked before it reaches the driver with the same reflex checks the strict
fake applies (`hamnet.fr3.reflexes.reflex_flags`: finite, inside the position limits,
velocity, acceleration and jerk from the samples already sent; an episode's first command
from rest at its first sample, which must lie within START_TOLERANCE of the measured
position), plus its gains and torque limits; one that fails is never sent: it becomes a
`command_rejected` error, which stops the stream like a reflex of the robot would. A reset
starts a new episode (new episode id), so that the safety filter plans again from the
measured joint positions instead of continuing a plan the robot stopped following; commands
computed for an older episode are ignored, and the episode's commands count their steps
afresh. A command answers a state the bridge published: one stamped with a later step is
forged or corrupt and is refused (`ahead`), so that it cannot make every genuine command
after it look stale. A reset that cannot reach the robot leaves the errors in place and
says why (`reset_failure`); the bridge stays up.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from hamnet.bridge.driver import (
    COMMAND_REJECTED,
    CONNECTION_LOST,
    STOP_REQUESTED,
    Driver,
    ImpedanceReference,
    RobotError,
    RobotReading,
)
from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.fr3.model import ee_pos_rot6d
from hamnet.fr3.reflexes import REFLEXES, reflex_flags
from hamnet.messages import robot_state, safe_command
from hamnet.messages.robot_state import StateIn
from hamnet.messages.safe_command import Command
from hamnet.proto.safety_pb2 import SafeCommand
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.errors import ConfigError

log = logging.getLogger(__name__)

START_TOLERANCE = 0.005
"""How far an episode's first reference may start from the last measured position, rad: a
resting arm settles by a fraction of a milliradian between the state the safety filter
planned from and the command's arrival; the driver starts tracking from where it is."""


@dataclass(frozen=True)
class BridgeCommand:
    """What the bridge needs of SafeCommand k."""

    step: int
    """k: the state the command answers."""
    episode_id: int
    """The episode the safety filter planned it for."""
    command: Command
    """References (1, S, J) and gains (1, J)."""


def decode_command(message: SafeCommand, samples: int, control_dt: float) -> BridgeCommand:
    """SafeCommand k for one robot: S = `samples` references at the driver's period
    `control_dt` (s), and the episode it was planned for (-1 when it names none).

    Raises:
        PayloadError: as `hamnet.messages.safe_command.decode` (another batch, sample count
            or sample period, non-finite values).
    """
    step, command = safe_command.decode(message, 1, samples, control_dt)
    episode = -1 if command.episode_ids is None else int(command.episode_ids[0])
    return BridgeCommand(step, episode, command)


class BridgeCore:
    """One robot: its driver, the stream's state (streaming or stopped by errors), episodes."""

    def __init__(self, driver: Driver, policy_period_s: float) -> None:
        """Connect and read the robot once; the stream starts at rest at its position."""
        self.driver = driver
        driver.connect()
        self.limits = driver.limits()
        samples = policy_period_s / driver.control_period_s
        if samples < 1 or abs(samples - round(samples)) > 1e-6:
            raise ConfigError(
                f"--policy-period-s {policy_period_s} is not a whole number of "
                f"the driver's {driver.control_period_s} s periods"
            )
        self.samples = round(samples)
        """S: reference samples per policy period."""
        self.errors: tuple[RobotError, ...] = ()
        """The errors that stopped the stream; empty while streaming."""
        self.episode_id = 0
        self.last_step = -1
        """Step of the last command sent to the driver."""
        self.counts = dict.fromkeys(("executed", "refused", "stale", "ahead"), 0)
        self.reset_failure = ""
        """Why the last reset could not reach or read the robot; '' after one that did."""
        self._measured = driver.read().q  # (J,) the last measured positions, rad
        self._history: np.ndarray | None = None  # (3, J) the last samples sent this episode

    @property
    def streaming(self) -> bool:
        """Whether commands reach the robot (no error since the last reset)."""
        return not self.errors

    def clock(self) -> float:
        """The robot's clock, s; once the link is lost (an error), the wall clock."""
        try:
            return self.driver.clock()
        except ConnectionError as error:
            self._fail([RobotError(CONNECTION_LOST, str(error))])
            return time.monotonic()

    def read(self) -> RobotReading | None:
        """The robot's state, or None when the connection is lost (then an error)."""
        try:
            reading = self.driver.read()
        except ConnectionError as error:
            self._fail([RobotError(CONNECTION_LOST, str(error))])
            return None
        self._measured = reading.q
        return reading

    def poll(self) -> list[RobotError]:
        """The driver's new errors; any of them stops the stream."""
        errors = self.driver.poll_errors()
        if errors:
            self._fail(errors)
        return errors

    def execute(self, command: BridgeCommand, newest_state: int) -> list[RobotError]:
        """Send one command to the robot if it may go; returns the errors it caused.
        `newest_state`: the step of the newest state published, the latest a genuine
        command can answer."""
        if command.step > newest_state:
            self.counts["ahead"] += 1
            return []
        if command.step <= self.last_step or command.episode_id != self.episode_id:
            self.counts["stale"] += 1
            return []
        if not self.streaming:
            self.counts["refused"] += 1
            return []
        problem = self.check(command.command)
        if problem:
            errors = [RobotError(COMMAND_REJECTED, problem)]
            self._fail(errors)
            return errors
        c = command.command
        q_ref = c.q_ref[0]  # (S, J)
        try:
            self.driver.send(ImpedanceReference(q_ref, c.kp[0], c.kd[0], c.tau_limit[0]))
        except ConnectionError as error:
            errors = [RobotError(CONNECTION_LOST, str(error))]
            self._fail(errors)
            return errors
        self.last_step = command.step
        self.counts["executed"] += 1
        self._history = q_ref[-3:]
        return self.poll()

    def check(self, command: Command) -> str:
        """Why a command must not reach the robot, or '' when it may."""
        shape = (1, self.samples, J)
        if np.shape(command.q_ref) != shape:
            return f"q_ref is {np.shape(command.q_ref)}, expected {shape}"
        gains = (command.kp, command.kd, command.tau_limit)
        if any(np.shape(g) != (1, J) or not np.all(np.isfinite(g)) for g in gains):
            return f"kp, kd and tau_limit must be finite, (1, {J})"
        if (command.kp < 0).any() or (command.kd < 0).any():
            return "negative stiffness or damping"
        if (command.tau_limit < 0).any() or (command.tau_limit > self.limits.tau_max).any():
            return "torque limits outside [0, tau_max]"
        first = command.q_ref[0, 0]  # (J,)
        if self._history is None:  # the episode's first command starts where the arm is
            offset = np.abs(first - self._measured).max()
            if offset > START_TOLERANCE:
                return f"starts {offset:.4f} rad from the measured position"
        history = np.repeat(first[None], 3, axis=0) if self._history is None else self._history
        q = np.concatenate([history, command.q_ref[0]])[None]  # (1, 3 + S, J)
        flags = reflex_flags(q, None, self.limits, self.driver.control_period_s)[0]  # (S, R)
        hit = flags.any(axis=1)
        if hit.any():
            tick = int(hit.argmax())
            names = [n for n, bad in zip(REFLEXES, flags[tick], strict=True) if bad]
            return f"sample {tick} would trigger {', '.join(names)}"
        return ""

    def stop(self, reason: str) -> None:
        """Stop the arm and the stream on request, as an error would."""
        self._fail([RobotError(STOP_REQUESTED, reason)])

    def reset(self) -> RobotReading | None:
        """Clear the errors (reconnecting if the link was lost) and start a new episode at
        the measured positions, its commands' steps counted afresh; None when the robot
        cannot be reached or read: the stream stays stopped and `reset_failure` says why."""
        try:
            if any(e.name == CONNECTION_LOST for e in self.errors):
                self.driver.connect()
            self.driver.reset()
        except ConnectionError as error:
            self.reset_failure = str(error)
            self._fail([RobotError(CONNECTION_LOST, str(error))])
            return None
        reading = self.read()
        if reading is None:
            self.reset_failure = "the robot could not be read after the reset"
            return None
        self.errors, self.reset_failure = (), ""
        self.episode_id += 1
        self.last_step = -1
        self._history = None
        return reading

    def _fail(self, errors: list[RobotError]) -> None:
        """Stop the arm and the stream; the first errors since the last reset are kept."""
        if self.streaming:
            self.errors = tuple(errors)
            log.warning(
                "robot error, stream stopped until a reset: %s",
                "; ".join(f"{e.name} ({e.reason})" for e in errors),
            )
        self.driver.stop()


def encode_state(
    reading: RobotReading,
    step: int,
    episode_id: int,
    episode_step: int,
    goal_pose: np.ndarray,
    object_pose: np.ndarray | None = None,
) -> RobotState:
    """RobotState k of one robot, as the sim publishes it but with no privileged block.

    Args:
        reading: the measured state; step: k; episode_id, episode_step: the episode's.
        goal_pose: (7,) the object's goal: position (m) and quaternion wxyz.
        object_pose: (7,) the object pose estimate, the same layout; None leaves the field
            out (a student policy then answers nothing, and safety holds the arm).
    """
    return robot_state.encode(
        StateIn(
            0,
            step,
            reading.q[None],
            reading.dq[None],
            np.array([episode_id]),
            np.array([episode_step]),
            tau=reading.tau[None],
            ee_pos_rot6d=ee_pos_rot6d(reading.ee_position, reading.ee_rotation)[None],
            goal_pose=np.asarray(goal_pose)[None],
            object_pose_estimate=None if object_pose is None else np.asarray(object_pose)[None],
        )
    )
