"""`hamnet camera`: depth frames of the robot's cameras on `camera/<w>/frames`, for
`hamnet perception --clouds-from cameras` (docs/cameras.md).

`--source sim` renders the paper's four virtual D435s looking at a procedural scene, with
the arm where the latest robot state (sim or bridge) puts it (MuJoCo over EGL);
`--source replay --replay.files F.mcap` republishes the frames of a recording;
`--source realsense --realsense.extrinsics poses.json` streams RealSense cameras (needs the
optional pyrealsense2).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Literal

from hamnet.camera.realsense import RealSenseConfig
from hamnet.camera.shell import PORTS, CameraShell
from hamnet.camera.sources import FrameSource, ReplayConfig, SimSourceConfig
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service
from hamnet.runtime.shell_config import ReportConfig

SourceName = Literal["sim", "replay", "realsense"]


@dataclass(frozen=True)
class CameraServiceConfig:
    """One robot's cameras: where the frames come from."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    source: SourceName = "sim"
    """sim (rendered virtual D435s), replay (a recording) or realsense (real cameras)."""
    sim: SimSourceConfig = field(default_factory=SimSourceConfig)
    replay: ReplayConfig = field(default_factory=ReplayConfig)
    realsense: RealSenseConfig = field(default_factory=RealSenseConfig)
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)


CONFIG = CameraServiceConfig
"""The config `hamnet camera` parses (the launcher validates stack files against it)."""


def make_source(config: CameraServiceConfig) -> FrameSource:
    """The chosen source (each imported only when chosen: MuJoCo, pyrealsense2).

    Raises:
        ConfigError: the source cannot start (a missing dependency or file).
    """
    if config.source == "sim":
        from hamnet.camera.sim_source import SimSource

        return SimSource(config.sim)
    if config.source == "replay":
        from hamnet.camera.sources import ReplaySource

        return ReplaySource(config.replay)
    from hamnet.camera.realsense import RealSenseSource

    return RealSenseSource(config.realsense)


def main(argv: Sequence[str]) -> int:
    """Run `hamnet camera` with command-line arguments `argv`; returns the exit status."""
    config, identity = parse_service(CONFIG, argv, "camera", __doc__, ports=PORTS)
    source = make_source(config)
    try:
        with Service(identity, config.common.transport, remap=config.common.remap) as service:
            return CameraShell(service, source, config.report).run()
    finally:
        source.close()
