"""The perception shell of the depth-camera path (`hamnet perception --clouds-from cameras`):
tokens for every robot state from the latest depth frames.

Consumes `camera/<w>/frames` (DepthFrames of the robot's cameras, `hamnet camera`) and
`sim/<w>/state` (RobotState of one robot, B = 1: the bridge, or a one-environment sim;
only its step, run and episode id are read, so no privileged block is needed). Produces
`perception/<w>/tokens` (PerceptionTokens with the state's step and episode id), the
message the policy pairs with the state, as the sim path (`shell.PerceptionShell`) does,
and `perception/<w>/object_pose` (ObjectPoseEstimate with the state's step: the object pose
estimated from the same frames, which the bridge puts in its next states).

Frames are processed as they arrive, on a thread of their own (at the cameras' rate; a
backlog is skipped to the newest; open3d and torch release the GIL), so that a state (at
the policy's rate) is answered at once from the newest percepts: the fusion and the encoder
stay off the path from state to command. A state that comes before any usable frame waits
(counted as `waiting_for_frames`) and is answered when one is processed. Frames that show
no object are counted (`nothing_seen`) and skipped. A state sent again gets the same answer,
an older one than the last answered is dropped, another run is followed, as on the sim path
(`hamnet.runtime.freshness`).
"""

from __future__ import annotations

import logging
import threading
import time

import numpy as np

from hamnet.camera.frames import decode_frames
from hamnet.camera.views import DepthView
from hamnet.messages.object_pose import encode as encode_pose
from hamnet.messages.robot_state import StateIn
from hamnet.messages.tokens import encode as encode_tokens
from hamnet.perception.camera_core import CameraPerception, NothingSeen
from hamnet.perception.core import Percepts
from hamnet.perception.messages import decode_step
from hamnet.perception.shell import PORTS, PerceptionLoopConfig
from hamnet.proto.camera_pb2 import DepthFrames
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.freshness import Answered, Verdict
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.service import Service

log = logging.getLogger(__name__)


class CameraPerceptionShell:
    """One perception worker answering states from depth frames."""

    def __init__(
        self, service: Service, core: CameraPerception, version: int, config: PerceptionLoopConfig
    ) -> None:
        self.service, self.core, self.version, self.config = service, core, version, config
        port = service.ports(PORTS)
        frames = payload_decoder(DepthFrames, decode_frames)
        service.inbox.subscribe("frames", port["frames"], decoder=frames)
        service.inbox.subscribe(
            "state", port["state"], decoder=payload_decoder(RobotState, decode_step)
        )
        self.tokens = service.publisher(port["tokens"])
        self.pose = service.publisher(port["object_pose"])
        self.frames: list[DepthView] | None = None
        """The newest frames not processed yet (guarded by `changed`)."""
        self.percepts: tuple[Percepts, np.ndarray] | None = None
        """Clouds, tokens and object pose (7,) of the newest frames that showed an object
        (guarded by `changed`)."""
        self.changed = threading.Condition()
        self.waiting: StateIn | None = None
        self.answered: Answered[PerceptionTokens] = Answered()
        """The state's run followed, the last step answered in it and its tokens."""
        self.report = LoopReport(config.report.report_period_s, self._line, logger=log)
        self.counts = self.report.counts
        """What happened since the last rate line."""

    def run(self) -> int:
        """Answer states until stopped; returns the exit status."""
        log.info(
            "clouds from camera frames; encoder version %d on %s", self.version, self.core.device
        )
        worker = threading.Thread(target=self._process_frames, name="frames", daemon=True)
        worker.start()
        try:
            while self.service.running:
                received = self.service.receive(timeout=0.01)
                if received is not None and received.name == "frames":
                    with self.changed:
                        self.frames = received.value
                        self.changed.notify()
                elif received is not None:
                    self._on_state(received.value)
                elif self.waiting is not None and self.percepts is not None:
                    state, self.waiting = self.waiting, None
                    self._on_state(state)
                self.report.tick()
        finally:
            with self.changed:
                self.changed.notify()
            worker.join()
        return 0

    def _process_frames(self) -> None:
        """Percepts of the newest frames, one frame set after the other, until stopped."""
        while self.service.running:
            with self.changed:
                self.changed.wait_for(lambda: self.frames is not None or not self.service.running)
                frames, self.frames = self.frames, None
            if frames is None:
                continue
            started = time.perf_counter()
            try:
                percepts = self.core.percepts(frames)
            except NothingSeen as error:
                self.counts["nothing_seen"] += 1
                log.debug("frames skipped: %s", error)
                continue
            with self.changed:
                self.percepts = percepts
            self.report.sample("frame_set_s", time.perf_counter() - started)

    def _on_state(self, state: StateIn) -> None:
        verdict = self.answered.follow(state.run, state.step)
        if verdict is Verdict.REPEAT:
            self.tokens.put(self.answered.message)
            self.counts["repeated"] += 1
            return
        if verdict in (Verdict.STALE, Verdict.IMPLAUSIBLE):
            self.counts[verdict.value] += 1
            return
        with self.changed:
            latest = self.percepts
        if latest is None:
            self.counts["waiting_for_frames"] += 1
            self.waiting = state
            return
        percepts, pose = latest
        message = encode_tokens(percepts, state.step, state.episode_ids, self.version)
        self.tokens.put(message)
        self.pose.put(encode_pose(pose, state.step))
        self.answered.answer(state.step, message)
        self.counts["published"] += 1

    def _line(self, w: Window) -> str:
        return (
            f"{w.rate('published'):.1f} token messages/s, median "
            f"{w.median_ms('frame_set_s'):.1f} ms per frame set, {w.count('repeated')} "
            f"repeated, {w.count('stale')} stale, {w.count('waiting_for_frames')} states "
            "waiting for frames, "
            f"{w.count('nothing_seen')} frames without an object"
        )
