"""The monitor's saved view never replaces a file: a restarted monitor, or a stack run
again, writes the next part of the sequence (`view.1.rrd`); closed, the file has Rerun's
footer (`rerun rrd verify` accepts it)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import rerun as rr

from hamnet.monitor.config import OutputConfig
from hamnet.monitor.outputs import add_footer, open_recording


def test_a_saved_view_goes_to_the_next_part_and_leaves_an_earlier_file_whole(tmp_path: Path) -> None:
    path = tmp_path / "view.rrd"
    path.write_bytes(b"an earlier run's view")
    for _ in range(2):
        recording, saved = open_recording(OutputConfig(save=path))
        recording.log("metrics/x", rr.Scalars(1.0))
        recording.disconnect()
        add_footer(saved)
    assert path.read_bytes() == b"an earlier run's view"
    assert (tmp_path / "view.1.rrd").stat().st_size > 0
    assert (tmp_path / "view.2.rrd").stat().st_size > 0


def verified(path: Path) -> bool:
    """Whether `rerun rrd verify` (footers checked, its default) accepts `path`: by what it
    prints, since Rerun 0.41 exits 0 either way."""
    command = [sys.executable, "-m", "rerun_cli", "rrd", "verify", str(path)]
    done = subprocess.run(command, check=False, capture_output=True, text=True, timeout=120)
    return "verified without error" in done.stdout + done.stderr


def test_a_closed_view_has_its_footer_and_passes_rerun_verify(tmp_path: Path) -> None:
    """Streamed without the footer (its index would grow the monitor's memory), the file
    gets it when the monitor closes it: Rerun's own check rejects it before, accepts it after."""
    recording, saved = open_recording(OutputConfig(save=tmp_path / "view.rrd"))
    for step in range(50):
        recording.set_time("step", sequence=step)
        recording.log("metrics/x", rr.Scalars(float(step)))
    recording.disconnect()
    assert not verified(saved)
    add_footer(saved)
    assert verified(saved)
