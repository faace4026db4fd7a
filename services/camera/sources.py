"""Where depth frames come from: the `FrameSource` interface and its three sources.

- `sim` (`sim_source.SimSource`): the four virtual D435s of the paper's rig render a
  procedurally generated one-environment scene, with the arm at the joint positions of the
  latest robot state (sim or bridge) and the renderer's segmentation as labels.
- `replay` (`ReplaySource`): the frames of an MCAP recording of `hamnet record`, at their
  recorded timing.
- `realsense` (`realsense.RealSenseSource`): RealSense cameras through pyrealsense2 (an
  optional dependency, imported only when chosen).

A source is polled by the shell between messages (`poll`), never blocks for long, and
says when it has nothing more to give (`done`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from hamnet.camera.frames import decode_frames
from hamnet.camera.views import DepthView
from hamnet.messages.robot_state import StateIn
from hamnet.proto.camera_pb2 import DepthFrames
from hamnet.runtime import contract
from hamnet.runtime.codec import parse
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.recordings import (
    RecordedMessage,
    ReplayClock,
    read_recording,
    selected,
    unreadable,
)
from hamnet.runtime.tensor import PayloadError

log = logging.getLogger(__name__)

FRAMES = contract.topic("camera/<w>/frames")


@dataclass(frozen=True)
class Frames:
    """One frame time of every camera."""

    step: int
    views: list[DepthView]
    names: list[str]


class FrameSource(Protocol):
    """A source of depth frames, polled by the camera shell."""

    needs_state: bool
    """Whether `poll` needs the robot's state (the shell subscribes to it)."""
    poll_s: float
    """How long the shell waits for messages between two polls, s."""
    done: bool
    """True once the source has nothing more (the end of a recording)."""

    def poll(self, robot: StateIn | None) -> Frames | None:
        """The next frames if there are new ones, else None (`robot`: the newest RobotState,
        whose first environment is the arm the cameras see)."""
        ...

    def close(self) -> None:
        """Release cameras, contexts and files."""
        ...


@dataclass(frozen=True)
class SimSourceConfig:
    """`--source sim`: the rendered scene and the image size."""

    seed: int = 0
    """Seed of the procedural scene (and of the object drawn into it)."""
    num_objects: int = 2
    """Objects of the library loaded (the first of the scene's draws is shown)."""
    width: int = 212
    """Image width, pixels (a D435 streams up to 848 x 480: rendering and fusing four of
    those every state is slow on a CPU)."""
    height: int = 120
    """Image height, pixels."""

    def __post_init__(self) -> None:
        if min(self.width, self.height, self.num_objects) < 1:
            raise ValueError("sim.width, sim.height and sim.num_objects must be >= 1")


@dataclass(frozen=True)
class ReplayConfig:
    """`--source replay`: the frames of a recording."""

    files: tuple[Path, ...] = ()
    """MCAP files of `hamnet record` (its rotated files in order); every camera/<w>/frames
    message in them is republished on this service's own key."""
    speed: float = 1.0
    """Recorded seconds per wall-clock second."""

    def __post_init__(self) -> None:
        if not self.speed > 0:
            raise ValueError(f"replay.speed must be > 0, got {self.speed}")


class ReplaySource:
    """Recorded frames at their recorded timing (times `speed`)."""

    needs_state = False
    poll_s = 0.005

    def __init__(self, config: ReplayConfig) -> None:
        problem = unreadable(list(config.files))
        if problem:
            raise ConfigError(f"--source replay: {problem}")
        self.speed = config.speed
        self.done = False
        self.dropped = 0
        self.messages: Iterator[RecordedMessage] = selected(
            read_recording(list(config.files)), (FRAMES.pattern,)
        )
        self.next: RecordedMessage | None = next(self.messages, None)
        self.clock: ReplayClock | None = None
        if self.next is None:
            raise ConfigError(
                f"--source replay: no {FRAMES.template} in {', '.join(map(str, config.files))}"
            )

    def poll(self, robot: StateIn | None) -> Frames | None:
        while self.next is not None:
            message = self.next
            if self.clock is None:
                self.clock = ReplayClock(message.log_time_ns, time.monotonic(), self.speed)
            if time.monotonic() < self.clock.due_s(message.log_time_ns):
                return None
            self.next = next(self.messages, None)
            try:
                frames = parse(DepthFrames, message.payload)
                return Frames(
                    frames.header.step, decode_frames(frames), [c.name for c in frames.cameras]
                )
            except PayloadError as error:
                self.dropped += 1
                log.warning("recorded frames on %s skipped: %s", message.key, error)
        self.done = True
        return None

    def close(self) -> None:
        self.messages = iter(())
