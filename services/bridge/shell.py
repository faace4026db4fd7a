"""The bridge's Zenoh shell: one robot in place of the sim, paced by the robot's clock.

Consumes `safety/<w>/command` (SafeCommand k: references at the driver's control period,
one policy period long, for one robot) and `perception/<w>/object_pose` (ObjectPoseEstimate
from the depth-camera path). Produces `sim/<w>/state` (RobotState, once per policy period:
the sim's fields for B = 1, no privileged block; the newest object pose estimate at most
`--pose-max-age-steps` states old as `object_pose_estimate`, or no such field, and then a
student policy answers nothing and safety holds the arm) and `bridge/<w>/event`
(SafetyEvent, kind ROBOT_ERROR on each robot error, ROBOT_RESET when the stream resumes).
Serves `bridge/<w>/reset` (`stop`, `reset`, `status`; JSON answers, the e-stop's latch of
`hamnet.safety.estop`): after an error the stream stays stopped until a `reset`. A reset
runs beside the loop (reconnecting to a robot can take seconds): meanwhile the loop goes on
pacing, reporting and answering `status`, and drops the commands that arrive (counted
`refused`); `status` says whether a reset is under way and why the last one failed, if it
did (`last_reset`).

Free-running: state k+1 goes out one policy period of the robot's clock (`Driver.clock`)
after state k, whatever the commands do (a robot clock that jumps back, as a reconnected
robot's may, restarts the pacing from it); each command is executed when it arrives if it
is newer than the last one, answers a state already published, and is planned for the
current episode (`hamnet.bridge.core`). A
command the transport cannot decode (non-finite, another sample period or batch) is dropped
and counted in health. Each executed command is timed from its state's publication: the
median and p99 of the last LATENCY_WINDOW go into the rate line and into health as figures
(`command_latency_median_ms`, `command_latency_p99_ms`).
"""

from __future__ import annotations

import functools
import logging
import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np

from hamnet.bridge.core import BridgeCommand, BridgeCore, encode_state
from hamnet.bridge.driver import RobotReading
from hamnet.messages import object_pose
from hamnet.messages.safe_command import decode as decode_command
from hamnet.messages.safety_event import encode as encode_event
from hamnet.proto.perception_pb2 import ObjectPoseEstimate
from hamnet.proto.safety_pb2 import SafeCommand, SafetyEventKind
from hamnet.runtime.codec import parse
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service
from hamnet.runtime.shell_config import Flattened, ReportConfig
from hamnet.safety.estop import EStop, on_query

log = logging.getLogger(__name__)

LATENCY_WINDOW = 1000
"""Commands over which the state-to-command latency percentiles are taken."""
LATENCY_HORIZON = 100
"""States kept for timing their commands: a later command is stale anyway."""

PORTS = Ports(
    inputs={
        "command": "safety/<w>/command",
        "object_pose": "perception/<w>/object_pose",
        "reset": "bridge/<w>/reset",
    },
    outputs={"state": "sim/<w>/state", "event": "bridge/<w>/event"},
)
"""What the bridge reads and writes (`hamnet.runtime.ports`)."""


@dataclass(frozen=True)
class BridgeLoopConfig:
    """Pace, goal and reporting of the bridge."""

    policy_period_s: float = 0.1
    """One state per this many seconds; commands must hold this many seconds of samples at
    the driver's period (run safety with the same `--trajectory.policy-period-s` and
    `--trajectory.control-rate-hz 1000`)."""
    goal_pose: tuple[float, float, float, float, float, float, float] = (
        0.5, 0.0, 0.05, 1.0, 0.0, 0.0, 0.0)  # fmt: skip
    """The object's goal published in every state: position (m), quaternion wxyz."""
    pose_max_age_steps: int = 5
    """Oldest object pose estimate put in a state, in states (its frames' state to this one)."""
    max_steps: int = 0
    """Exit after this many states (0: run until stopped)."""
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)

    def __post_init__(self) -> None:
        if self.max_steps < 0:
            raise ConfigError(f"--max-steps must be >= 0, got {self.max_steps}")
        if self.pose_max_age_steps < 1:
            raise ConfigError(f"--pose-max-age-steps must be >= 1, got {self.pose_max_age_steps}")


class BridgeShell:
    """One robot on the network: its state, its commands, its errors and its reset."""

    def __init__(self, service: Service, core: BridgeCore, loop: BridgeLoopConfig) -> None:
        self.service, self.core, self.loop = service, core, loop
        port = service.ports(PORTS)
        decoder = functools.partial(_decode_command_payload, samples=core.samples,
                                    control_dt=core.driver.control_period_s)  # fmt: skip
        service.inbox.subscribe("command", port["command"], decoder=decoder)
        service.inbox.subscribe("pose", port["object_pose"], decoder=_decode_pose)
        self.state = service.publisher(port["state"])
        self.event = service.publisher(port["event"])
        self.reset_key = port["reset"]
        self.requests = EStop()
        self.resets = ThreadPoolExecutor(max_workers=1, thread_name_prefix="bridge-reset")
        self.resetting: Future[RobotReading | None] | None = None
        """The reset under way, if any: until it ends the core is its thread's alone."""
        self.pending: deque[str] = deque()
        """E-stop requests taken but not applied yet (those after a reset wait for its end)."""
        self.last_reset: dict[str, object] | None = None
        """How the last reset ended, for `status`: step, ok, and the reason of a failure."""
        self.step = 0
        self.episode_step = 0
        self.reported: tuple = ()
        """The errors already published as events."""
        self.object_pose: tuple[int, np.ndarray] | None = None
        """The newest object pose estimate: (step of its frames, (7,) pose)."""
        self.published: dict[int, float] = {}
        """When each recent state went out (step -> monotonic s), to time its command."""
        self.latencies: deque[float] = deque(maxlen=LATENCY_WINDOW)
        """Seconds from a state's publication to the execution of its command, newest last."""
        self.report = LoopReport(loop.report.report_period_s, self._line, figures=self._figures,
                                 set_figure=service.set_figure, logger=log)  # fmt: skip

    def run(self) -> int:
        """Publish states and execute commands until stopped or `max_steps`; stops the arm
        and disconnects on the way out."""
        queryable = self.service.session.declare_queryable(
            self.reset_key, lambda query: on_query(self.requests, query)
        )
        log.info("%.0f ms policy period, %d samples per command, reset on %s",
                 1e3 * self.loop.policy_period_s, self.core.samples, self.reset_key)  # fmt: skip
        tick = self._clock()
        try:
            while self.service.running and not 0 < self.loop.max_steps <= self.step:
                if self._apply_requests():
                    tick = self._clock()  # a reconnected robot's clock may start anew
                if self.resetting is None:
                    self.core.poll()
                    self._publish_state()
                    self._report_errors()
                tick += self.loop.policy_period_s
                # a robot clock that stands still (a dead link) must not stall the states:
                # the next read then reports the lost connection
                wall_limit = time.monotonic() + 2 * self.loop.policy_period_s
                while (
                    self.service.running
                    and (remaining := tick - self._clock()) > 0
                    and (time.monotonic() < wall_limit)
                ):
                    received = self.service.receive(timeout=min(remaining, 0.01))
                    if received is not None and received.name == "pose":
                        self.object_pose = received.value
                    elif received is not None:
                        self._execute(received.value)
                tick = paced(tick, self._clock(), self.loop.policy_period_s)
                self.report.tick()
        finally:
            queryable.undeclare()
            self.resets.shutdown(wait=True)
            self.core.driver.close()
            self.report.flush()
        log.info("stopped after %d states, commands %s", self.step, self.core.counts)
        return 0

    def _clock(self) -> float:
        """The robot's clock (`BridgeCore.clock`); the wall clock while a reset has the core."""
        return time.monotonic() if self.resetting is not None else self.core.clock()

    def _publish_state(self) -> None:
        reading = self.core.read()
        if reading is None:
            return  # no link: no state (safety holds its last answer)
        goal = np.array(self.loop.goal_pose)
        pose = None
        if (
            self.object_pose is not None
            and self.step - self.object_pose[0] <= self.loop.pose_max_age_steps
        ):
            pose = self.object_pose[1]
        message = encode_state(
            reading, self.step, self.core.episode_id, self.episode_step, goal, pose
        )
        self.state.put(message)
        self.published[self.step] = time.monotonic()
        self.published.pop(self.step - LATENCY_HORIZON, None)
        self.step += 1
        self.episode_step += 1

    def _execute(self, command: BridgeCommand) -> None:
        """Execute a command, timing it from its state's publication when it went out."""
        if self.resetting is not None:
            self.core.counts["refused"] += 1
            return
        executed = self.core.counts["executed"]
        self.core.execute(command, self.step - 1)
        if self.core.counts["executed"] > executed and command.step in self.published:
            self.latencies.append(time.monotonic() - self.published.pop(command.step))
        self._report_errors()

    def _figures(self, w: Window) -> dict[str, float]:
        """The latency percentiles of the recent commands (a window of the newest, not of
        the rate line's period), in ms, for health and the rate line."""
        if not self.latencies:
            return {}
        median, p99 = 1e3 * np.percentile(self.latencies, [50, 99])
        return {"command_latency_median_ms": median, "command_latency_p99_ms": p99,
                "command_latency_count": len(self.latencies)}  # fmt: skip

    def _line(self, w: Window) -> str:
        stopped = [e.name for e in self.core.errors] or "nothing"
        line = f"step {self.step}, commands {self.core.counts}, stopped by {stopped}"
        if figures := self._figures(w):
            line += (f"; state to command: median {figures['command_latency_median_ms']:.1f} ms, "
                     f"p99 {figures['command_latency_p99_ms']:.1f} ms over the last "
                     f"{len(self.latencies)} commands")  # fmt: skip
        return line

    def _apply_requests(self) -> bool:
        """Apply the e-stop requests (a reset in its own thread, the others once no reset is
        under way) and update `status`; True when a reset has just ended well."""
        reset = self.resetting is not None and self.resetting.done() and self._finish_reset()
        self.pending.extend(self.requests.take())
        while self.resetting is None and self.pending:
            request = self.pending.popleft()
            if request == "stop":
                self.core.stop("stop requested")
            elif request == "reset":
                self.resetting = self.resets.submit(self.core.reset)
        self.requests.status = {"step": self.step, "streaming": self.core.streaming,
                                "errors": [e.name for e in self.core.errors],
                                "resetting": self.resetting is not None,
                                "last_reset": self.last_reset}  # fmt: skip
        return reset

    def _finish_reset(self) -> bool:
        """Take the ended reset's outcome: on success a new episode streams (ROBOT_RESET
        event); on failure the bridge stays up, stopped, and `status` says why."""
        reading, self.resetting = self.resetting.result(), None
        if reading is None:
            reason = self.core.reset_failure
            log.warning("reset at step %d failed, the stream stays stopped: %s", self.step, reason)
            self.last_reset = {"step": self.step, "ok": False, "reason": reason}
            return False
        self.last_reset = {"step": self.step, "ok": True, "reason": ""}
        self.reported, self.episode_step = (), 0
        log.info("reset at step %d: streaming again, episode %d", self.step, self.core.episode_id)
        self.event.put(encode_event(SafetyEventKind.ROBOT_RESET, self.step, np.zeros(1),
                                    "robot", "reset requested"))  # fmt: skip
        return True

    def _report_errors(self) -> None:
        """One ROBOT_ERROR event per error that stopped the stream, once."""
        for error in self.core.errors[len(self.reported) :]:
            self.service.count_event("robot_errors")
            self.event.put(encode_event(SafetyEventKind.ROBOT_ERROR, self.step, np.zeros(1),
                                        "robot", f"{error.name}: {error.reason}"))  # fmt: skip
        self.reported = self.core.errors


def paced(tick: float, now: float, period_s: float) -> float:
    """When the next state is due on the robot's clock: `tick`, or `now` when the clock is
    more than a period past it (the loop fell behind: no burst to catch up) or more than a
    period before it (the clock went back, as a reconnected robot's may: waiting for it
    would halve the rate)."""
    return tick if abs(now - tick) <= period_s else now


def _decode_command_payload(
    key: str, payload: bytes, samples: int, control_dt: float
) -> BridgeCommand:
    step, command = decode_command(parse(SafeCommand, payload), 1, samples, control_dt)
    episode = -1 if command.episode_ids is None else int(command.episode_ids[0])
    return BridgeCommand(step, episode, command)


def _decode_pose(key: str, payload: bytes) -> tuple[int, np.ndarray]:
    return object_pose.decode(parse(ObjectPoseEstimate, payload))
