"""scripts/student_memory.py measures where a shipped student departs from its teacher and
what its memory is worth (its full run is docs/trainer.md's DAgger diagnosis): a short run
keeps its invariants, and a teacher is refused."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import torch

from hamnet.trainer.algorithms.dagger import VelocityReadout
from tests.policy.inputs import informed
from tests.script_modules import load

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "student_memory.py"
student_memory = load("scripts/student_memory.py")


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
    assert all(math.isfinite(figures[k]) for k in ("velocity_loss_memory", "velocity_loss_reset"))


def test_the_velocity_read_out_is_scored_on_environments_it_was_not_fitted_on() -> None:
    """Memories that hold the velocity linearly read it back on the other half (loss near
    0); memories that do not read nothing (about 1 or worse: nothing to generalise)."""
    teacher, student = informed("hamnet"), informed("student")
    steps, b = 16, 32
    scale = VelocityReadout(student.memory_width, teacher)
    standardised = torch.randn(steps, b, 6)
    velocity = scale.mean + scale.std * standardised
    mix = torch.randn(6, student.memory_width)
    holding = standardised @ mix + 0.01 * torch.randn(steps, b, student.memory_width)
    assert student_memory.held_out_velocity_loss(holding, velocity, student, teacher) < 0.01
    unrelated = torch.randn(steps, b, student.memory_width)
    assert student_memory.held_out_velocity_loss(unrelated, velocity, student, teacher) > 0.9


def test_a_teacher_is_refused_with_the_reason() -> None:
    done = run("easy-paddle")
    assert done.returncode == 2
    assert "easy-paddle is not a recurrent student" in done.stderr
