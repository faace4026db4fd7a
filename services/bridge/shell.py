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
(`command_latency_median_ms`, `command_latency_p99_ms`). Without Zenoh: the core
(`hamnet.bridge.core`), the resets (`hamnet.bridge.resets`), the pacing and the command
timing (`hamnet.bridge.loop`).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from hamnet.bridge.core import BridgeCommand, BridgeCore, decode_command, encode_state
from hamnet.bridge.loop import BridgeLoopConfig, CommandLatency, paced
from hamnet.bridge.resets import Resets
from hamnet.messages import object_pose
from hamnet.messages.safety_event import encode as encode_event
from hamnet.proto.perception_pb2 import ObjectPoseEstimate
from hamnet.proto.safety_pb2 import SafeCommand, SafetyEventKind
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service
from hamnet.safety.estop import on_query

log = logging.getLogger(__name__)

PORTS = Ports(
    inputs={
        "command": "safety/<w>/command",
        "object_pose": "perception/<w>/object_pose",
        "reset": "bridge/<w>/reset",
    },
    outputs={"state": "sim/<w>/state", "event": "bridge/<w>/event"},
)
"""What the bridge reads and writes (`hamnet.runtime.ports`)."""


class BridgeShell:
    """One robot on the network: its state, its commands, its errors and its reset."""

    def __init__(self, service: Service, core: BridgeCore, loop: BridgeLoopConfig) -> None:
        self.service, self.core, self.loop = service, core, loop
        port = service.ports(PORTS)
        samples, control_dt = core.samples, core.driver.control_period_s
        command = lambda message: decode_command(message, samples, control_dt)
        service.inbox.subscribe(
            "command", port["command"], decoder=payload_decoder(SafeCommand, command)
        )
        pose = payload_decoder(ObjectPoseEstimate, object_pose.decode)
        service.inbox.subscribe("pose", port["object_pose"], decoder=pose)
        self.state = service.publisher(port["state"])
        self.event = service.publisher(port["event"])
        self.reset_key = port["reset"]
        self.resets = Resets(core)
        self.step = 0
        self.episode_step = 0
        self.reported: tuple = ()
        """The errors already published as events."""
        self.object_pose: tuple[int, np.ndarray] | None = None
        """The newest object pose estimate: (step of its frames, (7,) pose)."""
        self.latency = CommandLatency()
        """When recent states went out and how long their commands took."""
        self.report = LoopReport(
            loop.report.report_period_s,
            self._line,
            figures=lambda w: self.latency.figures(),
            set_figure=service.set_figure,
            logger=log,
        )

    def run(self) -> int:
        """Publish states and execute commands until stopped or `max_steps`; stops the arm
        and disconnects on the way out."""
        queryable = self.service.session.declare_queryable(
            self.reset_key, lambda query: on_query(self.resets.requests, query)
        )
        log.info(
            "%.0f ms policy period, %d samples per command, reset on %s",
            1e3 * self.loop.policy_period_s,
            self.core.samples,
            self.reset_key,
        )
        tick = self._clock()
        try:
            while self.service.running and not 0 < self.loop.max_steps <= self.step:
                if self.resets.apply(self.step):
                    self._reset_done()
                    tick = self._clock()  # a reconnected robot's clock may start anew
                if self.resets.resetting is None:
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
            self.resets.close()
            self.core.driver.close()
            self.report.flush()
        log.info("stopped after %d states, commands %s", self.step, self.core.counts)
        return 0

    def _clock(self) -> float:
        """The robot's clock (`BridgeCore.clock`); the wall clock while a reset has the core."""
        return time.monotonic() if self.resets.resetting is not None else self.core.clock()

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
        self.latency.published_state(self.step, time.monotonic())
        self.step += 1
        self.episode_step += 1

    def _execute(self, command: BridgeCommand) -> None:
        """Execute a command, timing it from its state's publication when it went out."""
        if self.resets.resetting is not None:
            self.core.counts["refused"] += 1
            return
        executed = self.core.counts["executed"]
        self.core.execute(command, self.step - 1)
        if self.core.counts["executed"] > executed:
            self.latency.executed(command.step, time.monotonic())
        self._report_errors()

    def _line(self, w: Window) -> str:
        stopped = [e.name for e in self.core.errors] or "nothing"
        line = f"step {self.step}, commands {self.core.counts}, stopped by {stopped}"
        if figures := self.latency.figures():
            line += (
                f"; state to command: median {figures['command_latency_median_ms']:.1f} ms, "
                f"p99 {figures['command_latency_p99_ms']:.1f} ms over the last "
                f"{figures['command_latency_count']} commands"
            )
        return line

    def _reset_done(self) -> None:
        """A reset ended well: a new episode streams (ROBOT_RESET event)."""
        self.reported, self.episode_step = (), 0
        event = encode_event(
            SafetyEventKind.ROBOT_RESET, self.step, np.zeros(1), "robot", "reset requested"
        )
        self.event.put(event)

    def _report_errors(self) -> None:
        """One ROBOT_ERROR event per error that stopped the stream, once."""
        for error in self.core.errors[len(self.reported) :]:
            self.service.count_event("robot_errors")
            reason = f"{error.name}: {error.reason}"
            event = encode_event(
                SafetyEventKind.ROBOT_ERROR, self.step, np.zeros(1), "robot", reason
            )
            self.event.put(event)
        self.reported = self.core.errors
