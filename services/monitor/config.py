"""Configuration of the monitor: what it shows (`ViewConfig`), where the Rerun data goes
(`OutputConfig`) and how its loop keeps up with the stack (`MonitorLoopConfig`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

from hamnet.monitor.blueprint import Layout
from hamnet.runtime.shell_config import Flattened, ReportConfig


@dataclass(frozen=True)
class ViewConfig:
    """What the view shows and how often."""

    env: int = 0
    """Environment in focus: its index in the batch of the watched sim worker (`--worker`)."""
    max_rate_hz: float = 30.0
    """At most this many steps per second are drawn (robot, clouds, module weights, reward
    terms); the others are skipped and counted as drops with reason `rate`. Above the
    policy rate (10 Hz) nothing is skipped in real time; a faster lock-step sim is thinned."""
    success_window: int = 100
    """Finished episodes (of every environment of the worker) the success rate averages."""
    layout: Layout = "stack"
    """The viewer's layout (`hamnet.monitor.blueprint`): stack, the whole stack around the
    environment in focus; training, the trainer's curves and update statistics alone, for
    a training run whose namespace has no sim (rollout workers publish no scenes)."""

    def __post_init__(self) -> None:
        if self.env < 0:
            raise ValueError(f"env must be >= 0, got {self.env}")
        if not self.max_rate_hz > 0.0:
            raise ValueError(f"max_rate_hz must be > 0, got {self.max_rate_hz}")
        if self.success_window < 1:
            raise ValueError(f"success_window must be >= 1, got {self.success_window}")

    @property
    def min_frame_interval_s(self) -> float:
        """Shortest wall time between two drawn steps, s."""
        return 1.0 / self.max_rate_hz


@dataclass(frozen=True)
class OutputConfig:
    """Where the Rerun data goes: any combination, at least one."""

    spawn: bool = False
    """Start a Rerun viewer on this machine and stream to it (port `--viewer-port`)."""
    connect_viewer: str | None = None
    """Stream to a running viewer at this URL, e.g. rerun+http://127.0.0.1:9876/proxy
    (`--connect` is taken by Zenoh)."""
    serve_web: bool = False
    """Serve the data and a web viewer: open http://localhost:<web-port> in a browser."""
    save: Path | None = None
    """Write everything to this .rrd file (headless); open it later with `rerun FILE`. An
    existing file is kept: the view then goes to FILE's next free part (`view.1.rrd`)."""
    viewer_port: int = 9876
    """gRPC port of the spawned viewer (`--spawn`) or of the served data (`--serve-web`)."""
    web_port: int = 9090
    """HTTP port of the web viewer (`--serve-web`)."""

    def __post_init__(self) -> None:
        if self.spawn and self.serve_web:
            raise ValueError("--spawn and --serve-web both listen on --viewer-port: choose one")

    @property
    def chosen(self) -> bool:
        """Whether any output is chosen (the defaults choose none: the monitor refuses to
        run unseen)."""
        return bool(self.spawn or self.connect_viewer or self.serve_web or self.save)


@dataclass(frozen=True)
class MonitorLoopConfig:
    """How the monitor's loop keeps up."""

    inbox_capacity: int = 64
    """Payloads waiting to be drawn; when full the oldest is dropped (reason `overflow`), so
    a slow viewer never queues without bound nor slows the publishers."""
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)

    def __post_init__(self) -> None:
        if self.inbox_capacity < 1:
            raise ValueError(f"inbox_capacity must be >= 1, got {self.inbox_capacity}")
