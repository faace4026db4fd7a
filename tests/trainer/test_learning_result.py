"""A shortened `scripts/ppo_easy.py` (the easy-stage result, docs/results/ppo-easy.json):
both runs finish, the result and its curves are written, and the state-based baseline
learns as the hour's curve says it does.

The threshold, from the hour's curve (docs/results/ppo-easy.json, `baseline_curve`): the
baseline's training success over the last 200 episodes averaged 0.026 over its first 50 k
transitions and 0.029 over the next 50 k, then 0.069 (never below 0.04) between 200 k and
300 k. A mean of at least 0.045 over 200-300 k therefore says it learned; the untrained
start's 0.03 does not reach it. HAMnet's curve shows no comparable rise in such a short
run (0.02-0.05 over its first 0.1 M transitions), so for it the test checks the run only.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_a_short_easy_stage_result_is_written_and_the_baseline_learns(tmp_path: Path) -> None:
    out = tmp_path / "result"
    subprocess.run([sys.executable, str(ROOT / "scripts" / "ppo_easy.py"), "--minutes", "9", "--eval-episodes", "32",
                    "--runs", str(tmp_path / "runs"), "--out", str(out)], check=True, timeout=1200)  # fmt: skip
    result = json.loads(out.with_suffix(".json").read_text())
    assert out.with_suffix(".png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for key in ("final_success_rate", "baseline_final_success_rate", "final_goal_return", "env_steps",
                "wall_clock_s", "stage_definition", "curve", "baseline_curve", "command", "seed", "commit"):  # fmt: skip
        assert result[key] is not None, key
    assert result["env_steps"] > 0 and result["stage"] == "easy"
    window = [row["success_rate"] for row in result["baseline_curve"]
              if 200_000 <= row["env_transitions"] < 300_000]  # fmt: skip
    assert window, "the baseline did not reach 300 k transitions in 9 minutes"
    assert statistics.mean(window) >= 0.045
