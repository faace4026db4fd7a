"""`--source realsense`: Intel RealSense depth cameras (the paper's four D435s) through
pyrealsense2, an optional dependency imported only when this source is chosen.

Not tested here (no cameras): kept small. Each camera streams depth (z16) at the configured
size and rate; its pinhole intrinsics come from the stream, its depth scale from the device,
its pose in the robot's world frame from `--realsense.extrinsics` (a JSON object: serial ->
4x4 camera-to-world matrix, OpenCV axes, from a hand-eye or target calibration). A frame set
goes out once every camera has a new frame. The frames carry no labels: perception splits
them with `--segmenter plane` (docs/cameras.md says what a real setup still needs).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hamnet.camera.sources import Frames
from hamnet.camera.views import DepthView
from hamnet.messages.robot_state import StateIn
from hamnet.runtime.errors import ConfigError


@dataclass(frozen=True)
class RealSenseConfig:
    """`--source realsense`: which cameras, how they stream, where they are."""

    extrinsics: Path | None = None
    """JSON file: {serial: 4x4 camera-to-world matrix (OpenCV axes, m)}; its serials are
    the cameras used."""
    width: int = 640
    """Depth stream width, pixels."""
    height: int = 480
    """Depth stream height, pixels."""
    fps: int = 30
    """Depth stream rate, frames/s."""


def load_extrinsics(path: Path) -> dict[str, np.ndarray]:
    """{serial: (4, 4) camera-to-world} from `path`; ConfigError when unusable."""
    try:
        poses = {
            serial: np.asarray(matrix, np.float64)
            for serial, matrix in json.loads(path.read_text()).items()
        }
    except (OSError, ValueError, AttributeError) as error:
        raise ConfigError(f"--realsense.extrinsics {path}: {error}") from None
    if not poses or any(pose.shape != (4, 4) for pose in poses.values()):
        raise ConfigError(
            f"--realsense.extrinsics {path}: needs {{serial: 4x4 matrix}} for at least one camera"
        )
    return poses


class RealSenseSource:
    """The configured RealSense cameras, polled without blocking."""

    needs_state = False
    poll_s = 0.002
    done = False

    def __init__(self, config: RealSenseConfig) -> None:
        try:
            import pyrealsense2 as rs
        except ImportError:
            raise ConfigError(
                "--source realsense needs pyrealsense2, which is not installed "
                "(pip install pyrealsense2)"
            ) from None
        if config.extrinsics is None:
            raise ConfigError(
                "--source realsense needs --realsense.extrinsics (serial -> camera-to-world)"
            )
        self.poses = load_extrinsics(config.extrinsics)
        self.pipelines, self.scales, self.intrinsics = {}, {}, {}
        for serial in self.poses:
            rs_config = rs.config()
            rs_config.enable_device(serial)
            rs_config.enable_stream(
                rs.stream.depth, config.width, config.height, rs.format.z16, config.fps
            )
            pipeline = rs.pipeline()
            profile = pipeline.start(rs_config)
            self.scales[serial] = profile.get_device().first_depth_sensor().get_depth_scale()
            k = profile.get_stream(rs.stream.depth).as_video_stream_profile().get_intrinsics()
            self.intrinsics[serial] = np.array(
                [[k.fx, 0, k.ppx], [0, k.fy, k.ppy], [0, 0, 1]], np.float64
            )
            self.pipelines[serial] = pipeline
        self.latest: dict[str, np.ndarray] = {}
        self.count = 0

    def poll(self, robot: StateIn | None) -> Frames | None:
        for serial, pipeline in self.pipelines.items():
            frameset = pipeline.poll_for_frames()
            if frameset:
                raw = np.asanyarray(frameset.get_depth_frame().get_data())
                self.latest[serial] = (raw * self.scales[serial]).astype(np.float32)
        if len(self.latest) < len(self.pipelines):
            return None
        views = [
            DepthView(self.latest[s], None, self.intrinsics[s], self.poses[s])
            for s in self.pipelines
        ]
        names = list(self.pipelines)
        self.latest.clear()
        self.count += 1
        return Frames(self.count, views, names)

    def close(self) -> None:
        for pipeline in self.pipelines.values():
            pipeline.stop()
