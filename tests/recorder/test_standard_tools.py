"""Recordings open in a standard MCAP tool that knows nothing of hamnet: Rerun's own `rerun
mcap check` passes them, and `rerun mcap convert --decoder protobuf` decodes every field of
the contract's messages from the schemas stored in the file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import rerun

from tests.recorder.recordings import RAW, STATE, TRANSITION, lock_step, write

RERUN = Path(sys.executable).parent / "rerun"
ENV = {**os.environ, "CI": "1"}  # no first-run analytics prompt


def test_rerun_checks_the_file_and_decodes_its_protobuf_channels(tmp_path: Path) -> None:
    write(tmp_path / "a.mcap", lock_step(5))
    check = subprocess.run([RERUN, "mcap", "check", tmp_path / "a.mcap"], capture_output=True,
                           text=True, timeout=60, env=ENV)  # fmt: skip
    assert check.returncode == 0, check.stderr
    for key in (STATE, TRANSITION, RAW):
        assert any(line.startswith("ok") and key in line for line in check.stdout.splitlines())
    convert = subprocess.run(
        [RERUN, "mcap", "convert", tmp_path / "a.mcap", "-d", "protobuf", "-o", tmp_path / "a.rrd"],
        capture_output=True, text=True, timeout=60, env=ENV,
    )  # fmt: skip
    assert convert.returncode == 0, convert.stderr
    states = []
    for chunk in rerun.chunk.RrdReader(tmp_path / "a.rrd").stream().to_chunks():
        if str(chunk.entity_path) == f"/{STATE}":
            states += chunk.to_record_batch().column("hamnet.RobotState:message").to_pylist()
    decoded = [row[0] for row in states]
    assert [s["header"]["step"] for s in decoded] == [0, 0, 1, 2, 3, 4]
    assert decoded[3]["q"]["shape"] == [2, 7] and decoded[3]["q"]["dtype"]["name"] == "FLOAT32"
