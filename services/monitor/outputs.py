"""Where the monitor's Rerun data goes: one recording stream teed to every chosen output
(a viewer it spawns, a viewer at a URL, a served web viewer, an .rrd file), each getting
the default layout (`hamnet.monitor.blueprint`).

The .rrd file is streamed without Rerun's footer: the footer indexes every chunk and Rerun
keeps that index in memory until the file closes, which grew the monitor by about the
file's size over a long run (issue 13). The file is still a valid recording; `rerun rrd
optimize` adds the index afterwards where random access matters."""

from __future__ import annotations

import logging

import rerun as rr

from hamnet.monitor.blueprint import blueprint
from hamnet.monitor.config import OutputConfig

log = logging.getLogger(__name__)

APPLICATION_ID = "hamnet_monitor"
"""Rerun application id: the viewer keeps one layout per application."""


def local_url(port: int) -> str:
    """gRPC URL of a Rerun server on this machine."""
    return f"rerun+http://127.0.0.1:{port}/proxy"


def open_recording(output: OutputConfig) -> rr.RecordingStream:
    """A recording stream that writes to every output `output` chooses.

    Raises:
        ValueError: when no output is chosen.
    """
    if not output.chosen:
        raise ValueError("choose where the view goes: --spawn, --connect-viewer URL, "
                         "--serve-web or --save FILE.rrd (any combination)")  # fmt: skip
    sinks: list[object] = []
    if output.save is not None:
        output.save.parent.mkdir(parents=True, exist_ok=True)
        sinks.append(rr.FileSink(str(output.save), write_footer=False))
    if output.spawn:
        rr.spawn(port=output.viewer_port, connect=False)
        sinks.append(rr.GrpcSink(local_url(output.viewer_port)))
    if output.connect_viewer:
        sinks.append(rr.GrpcSink(output.connect_viewer))
    if output.serve_web:
        sinks.append(rr.GrpcServerSink(port=output.viewer_port))
    recording = rr.RecordingStream(APPLICATION_ID)
    recording.set_sinks(*sinks, default_blueprint=blueprint())
    if output.serve_web:
        rr.serve_web_viewer(web_port=output.web_port, open_browser=False,
                            connect_to=local_url(output.viewer_port))  # fmt: skip
        log.info("web viewer on http://localhost:%d", output.web_port)
    if output.save is not None:
        log.info("writing %s", output.save)
    return recording
