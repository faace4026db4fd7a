"""A shortened distillation (issue 15), as a user runs it: `hamnet trainer --algo dagger`
distils the shipped guided teacher `easy-guided` into the student on the easy stage, with
the command and settings of docs/results/dagger-easy-guided-replay.json, and the student
learns to act as the teacher does on states it has not been trained on.

The threshold, from that run's curve (`curve`, the imitation loss measured before each
update on a window the student has not fitted yet, averaged per 3 k transitions): 0.368 on
the first window, 0.047 by 7 k transitions, 0.020-0.022 from 10 k to 16 k, 0.005-0.009
later. Over the last quarter of 16 k transitions a mean below 0.06 therefore says the
student learned the teacher's map (about 3x margin over the curve), and a first window at
least 3x above that mean says it did not start there (the curve's ratio is about 17x). A
teacher of a few PPO updates would not do: its map is near constant and both losses are
about 1e-5, so nothing separates learning from not learning. Success rates of
32-episode evaluations move by +-0.08 around the pair's 0.3-0.4, so they are checked as
written, not compared.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_short_distillation_imitates_its_teacher(tmp_path: Path) -> None:
    run = tmp_path / "student"
    command = ["trainer", "--algo", "dagger", "--inprocess", "--teacher", "easy-guided",
               "--stage", "easy", "--sim.seed", "0", "--steps-per-rollout", "8",
               "--max-env-transitions", "16384", "--eval-episodes", "32", "--run-dir", str(run)]  # fmt: skip
    subprocess.run([sys.executable, "-m", "hamnet", *command], check=True, timeout=800)

    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    losses = [row["imitation_loss"] for row in rows]
    last_quarter = [row["imitation_loss"] for row in rows if row["env_transitions"] > 12_288]
    assert last_quarter, "the run ended before 12 k transitions"
    assert statistics.mean(last_quarter) < 0.06
    assert losses[0] > 3 * statistics.mean(last_quarter)
    assert rows[-1]["beta"] < rows[0]["beta"]  # the student took over part of the acting

    summary = json.loads((run / "summary.json").read_text())
    assert summary["algo"] == "dagger" and summary["eval_episodes"] == 32
    for key in ("teacher_success_rate", "student_success_rate"):
        assert 0.0 <= summary[key] <= 1.0, key
