"""Where the monitor's Rerun data goes: one recording stream teed to every chosen output
(a viewer it spawns, a viewer at a URL, a served web viewer, an .rrd file), each getting
the chosen layout (`hamnet.monitor.blueprint`).

The .rrd file is streamed without Rerun's footer: the footer indexes every chunk and Rerun
keeps that index in memory until the file closes, which grew the monitor by about the
file's size over a long run (issue 13). When the monitor ends (its duration, SIGTERM,
Ctrl-C, an error) the file gets its footer from a short-lived `rerun rrd merge`
(`add_footer`), so `rerun rrd verify` accepts it; a monitor killed outright leaves it as
streamed, still readable. Like the recorder, the monitor never replaces a file: when FILE
exists (a monitor restarted, a stack run again) the view goes to the next free part,
`view.1.rrd`, `view.2.rrd`, ... (`hamnet.runtime.numbered_files`)."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import rerun as rr

from hamnet.monitor.blueprint import Layout, blueprint
from hamnet.monitor.config import OutputConfig
from hamnet.runtime.numbered_files import next_part

log = logging.getLogger(__name__)

APPLICATION_ID = "hamnet_monitor"
"""Rerun application id: the viewer keeps one layout per application."""


def local_url(port: int) -> str:
    """gRPC URL of a Rerun server on this machine."""
    return f"rerun+http://127.0.0.1:{port}/proxy"


def open_recording(
    output: OutputConfig, layout: Layout = "stack"
) -> tuple[rr.RecordingStream, Path | None]:
    """A recording stream that writes to every output `output` chooses, each getting the
    layout `layout`, and the .rrd file it saves to (None: no file).

    Raises:
        ValueError: when no output is chosen.
    """
    if not output.chosen:
        raise ValueError(
            "choose where the view goes: --spawn, --connect-viewer URL, "
            "--serve-web or --save FILE.rrd (any combination)"
        )
    sinks: list[object] = []
    saved = None if output.save is None else next_part(output.save)
    if saved is not None:
        saved.parent.mkdir(parents=True, exist_ok=True)
        sinks.append(rr.FileSink(str(saved), write_footer=False))
    if output.spawn:
        rr.spawn(port=output.viewer_port, connect=False)
        sinks.append(rr.GrpcSink(local_url(output.viewer_port)))
    if output.connect_viewer:
        sinks.append(rr.GrpcSink(output.connect_viewer))
    if output.serve_web:
        sinks.append(rr.GrpcServerSink(port=output.viewer_port))
    recording = rr.RecordingStream(APPLICATION_ID)
    recording.set_sinks(*sinks, default_blueprint=blueprint(layout))
    if output.serve_web:
        rr.serve_web_viewer(
            web_port=output.web_port, open_browser=False, connect_to=local_url(output.viewer_port)
        )
        log.info("web viewer on http://localhost:%d", output.web_port)
    if saved is not None:
        log.info("writing %s", saved)
    return recording, saved


def add_footer(path: Path) -> None:
    """Close a streamed .rrd file as Rerun closes its own: with the footer that indexes its
    chunks (`rerun rrd verify` rejects a file without one). `rerun rrd merge` rewrites the
    file into one with a footer (`route`, which copies without decoding, writes none), which
    then replaces it; the index is built in that short-lived process, not in the monitor. A
    failed rewrite leaves the file as it was streamed, still readable, and says why."""
    finished = path.with_name(f"{path.stem}.closing{path.suffix}")
    command = [sys.executable, "-m", "rerun_cli", "rrd", "merge", str(path), "-o", str(finished)]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0 or not finished.is_file():
        log.warning("%s stays without its footer: %s", path, done.stderr.strip()[-500:])
        finished.unlink(missing_ok=True)
        return
    os.replace(finished, path)
