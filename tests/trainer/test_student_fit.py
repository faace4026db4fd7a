"""scripts/student_fit.py measures what limits a student's fit of its teacher (its full run is
docs/trainer.md's diagnosis of the guided student): its schedules step as they say, and a
short run reports every figure for the student as trained and each refit."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from tests.script_modules import load

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "student_fit.py"
student_fit = load("scripts/student_fit.py")


def test_as_run_steps_each_window_in_turn_and_aggregated_draws_with_a_falling_rate() -> None:
    windows = ["a", "b", "c", "d"]
    steps = list(student_fit.as_run(windows, epochs=2, lr=1e-3)())
    assert steps == [([w], 1e-3) for w in windows for _ in range(2)]
    drawn = list(student_fit.aggregated(windows, batch=2, passes=3, lr=1e-3, seed=0)())
    assert len(drawn) == 3 * 4 // 2
    assert all(len(set(batch)) == 2 and set(batch) <= set(windows) for batch, _ in drawn)
    rates = [lr for _, lr in drawn]
    assert rates[0] == 1e-3 and rates == sorted(rates, reverse=True) and rates[-1] > 0
    assert rates == pytest.approx([1e-3 * (1 - i / 6) for i in range(6)])


def test_a_short_run_reports_the_trained_student_and_each_refit() -> None:
    command = [sys.executable, str(SCRIPT), "easy-paddle-student", "--windows", "2",
               "--held-out", "2", "--steps", "2", "--batch-windows", "1", "--passes", "1"]  # fmt: skip
    done = subprocess.run(command, check=False, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    arms = {"run", "as_run", "as_run_tenth_lr", "aggregated"}
    assert set(figures["held_out_loss"]) == set(figures["own_states_loss"]) == arms
    losses = [*figures["held_out_loss"].values(), *figures["own_states_loss"].values()]
    assert all(math.isfinite(x) and x > 0 for x in losses)
    held = figures["held_out_loss"]
    assert len({held[arm] for arm in arms}) == len(arms)  # each refit moved the weights
    assert -1 <= figures["gradient_cosine"] <= 1 and figures["success"] == {}
