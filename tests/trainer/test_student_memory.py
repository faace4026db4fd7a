"""scripts/student_memory.py measures where a shipped student departs from its teacher and
what its memory is worth (its full run is docs/trainer.md's DAgger diagnosis): a short run
keeps its invariants, and a teacher is refused."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "student_memory.py"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, str(SCRIPT), *args]
    return subprocess.run(command, check=False, capture_output=True, text=True, timeout=300)


def test_a_short_run_bins_every_step_and_memory_is_nothing_at_an_episode_start() -> None:
    done = run("easy-paddle-student", "--steps", "6")
    assert done.returncode == 0, done.stderr
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    bins = figures["bins"]
    assert [b["steps"] for b in bins] == [[0, 1], [1, 4], [4, 6]]
    assert sum(b["samples"] for b in bins) == 6 * 64  # every step of the 64 environments
    first = bins[0]
    assert first["mse_memory"] == first["mse_reset"]  # the acted memory is the initial one
    later = bins[1:]
    assert all(b["mse_memory"] != b["mse_reset"] for b in later)  # history changes actions
    assert all(0 < b["label_mean_square"] < 1 for b in bins)


def test_a_teacher_is_refused_with_the_reason() -> None:
    done = run("easy-paddle")
    assert done.returncode == 2
    assert "easy-paddle is not a recurrent student" in done.stderr
