"""The camera service's Zenoh shell: polls a frame source and publishes its frames.

Consumes `sim/<w>/state` (RobotState: the arm's joint positions, for the `sim` source only;
the newest state wins, older queued ones are skipped). Produces `camera/<w>/frames`
(DepthFrames: every camera of the rig at one frame time). Ends when the source is done (the
end of a recording) or on a signal.
"""

from __future__ import annotations

import logging
import time

from hamnet.camera.frames import encode_frames
from hamnet.camera.sources import FrameSource
from hamnet.messages import robot_state
from hamnet.messages.robot_state import StateIn
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service
from hamnet.runtime.shell_config import ReportConfig
from hamnet.runtime.tensor import PayloadError

log = logging.getLogger(__name__)

PORTS = Ports(
    inputs={"state": "sim/<w>/state"},
    outputs={"frames": "camera/<w>/frames"},
)
"""What the camera service reads and writes (`hamnet.runtime.ports`)."""


def decode_pose(message: RobotState) -> StateIn:
    """RobotState k for a source that renders the arm: `q` of at least one environment.

    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    state = robot_state.decode(message, required=("q",))
    if len(state.q) == 0:
        raise PayloadError("shape", "RobotState.q holds no environment")
    return state


class CameraShell:
    """Publishes one source's frames on `camera/<w>/frames`."""

    def __init__(
        self, service: Service, source: FrameSource, report: ReportConfig | None = None
    ) -> None:
        self.service, self.source = service, source
        report = report if report is not None else ReportConfig()
        self.report = LoopReport(report.report_period_s, self._line, logger=log)
        port = service.ports(PORTS)
        if source.needs_state:
            decoder = payload_decoder(RobotState, decode_pose)
            service.inbox.subscribe("state", port["state"], decoder=decoder)
        self.frames = service.publisher(port["frames"])
        self.robot: StateIn | None = None
        self.published = 0

    def run(self) -> int:
        """Publish frames until the source is done or the service stops."""
        while self.service.running and not self.source.done:
            received = self.service.receive(timeout=self.source.poll_s)
            while received is not None:  # the newest state wins
                self.robot = received.value
                received = self.service.receive(timeout=0)
            started = time.perf_counter()
            frames = self.source.poll(self.robot)
            if frames is not None:
                self.frames.put(encode_frames(frames.views, frames.step, frames.names))
                self.published += 1
                self.report.sample("frame_set_s", time.perf_counter() - started)
            self.report.tick()
        log.info("published %d frame sets", self.published)
        return 0

    def _line(self, w: Window) -> str:
        made = len(w.samples.get("frame_set_s", ()))
        return (
            f"{made / w.seconds:.1f} frame sets/s, median {w.median_ms('frame_set_s'):.1f} "
            "ms to make one"
        )
