"""A shortened `scripts/ppo_easy.py` (the easy-stage result, docs/results/ppo-easy.json):
both runs finish, the result and its curves are written, and the state-based baseline
learns as the hour's curve says it does.

The threshold, from the hour's curve on issue 28's easy stage (docs/results/ppo-easy.json,
`baseline_curve`; per-iteration rows in the run's metrics): the baseline's training success
over the last 200 episodes was 0.005-0.045 (mean 0.020) over its first 100 k transitions,
then 0.065-0.10 (mean 0.084) between 300 k and 400 k, which it passes after about 8
minutes side by side with HAMnet. A mean of at least 0.05 over 300-400 k therefore says it
learned; the untrained start's 0.02 does not reach it. HAMnet's curve rises too slowly for
such a short run (0.021, 0.027 over its first two 0.1 M), so for it the test checks the run
and the result's fields only.
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
@pytest.mark.timeout(1500)  # the script runs 10 minutes, then evaluates both policies
def test_a_short_easy_stage_result_is_written_and_the_baseline_learns(tmp_path: Path) -> None:
    out = tmp_path / "result"
    subprocess.run([sys.executable, str(ROOT / "scripts" / "ppo_easy.py"), "--minutes", "10", "--eval-episodes", "32",
                    "--runs", str(tmp_path / "runs"), "--out", str(out)], check=True, timeout=1200)  # fmt: skip
    result = json.loads(out.with_suffix(".json").read_text())
    assert out.with_suffix(".png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for key in ("final_success_rate", "baseline_final_success_rate", "final_goal_return", "env_steps",
                "wall_clock_s", "stage_definition", "curve", "baseline_curve", "command", "seed", "commit",
                "eval_episodes", "within_0.05m", "median_final_distance_m", "median_start_distance_m"):  # fmt: skip
        assert result[key] is not None, key
    assert result["env_steps"] > 0 and result["stage"] == "easy"
    window = [row["success_rate"] for row in result["baseline_curve"]
              if 300_000 <= row["env_transitions"] < 400_000]  # fmt: skip
    assert window, "the baseline did not reach 400 k transitions in 10 minutes"
    assert statistics.mean(window) >= 0.05
    assert result["median_start_distance_m"] >= 0.15  # the stage's pushes


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_both_runs_continue_from_their_snapshots_with_resume(tmp_path: Path) -> None:
    """`--resume` continues both runs (HAMnet through its rollout worker, the baseline in
    process) where they stopped, until `--minutes` over both starts: their transitions go on
    from the first run's instead of starting again."""
    script = [sys.executable, str(ROOT / "scripts" / "ppo_easy.py"), "--eval-episodes", "4",
              "--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "result")]  # fmt: skip
    subprocess.run([*script, "--minutes", "1.5"], check=True, timeout=400)
    first = json.loads((tmp_path / "result.json").read_text())
    subprocess.run([*script, "--minutes", "3", "--resume"], check=True, timeout=400)
    second = json.loads((tmp_path / "result.json").read_text())
    assert second["env_steps"] > first["env_steps"] > 0
    assert second["baseline_env_steps"] > first["baseline_env_steps"] > 0
    assert second["command"].endswith("--resume")
    for name in ("hamnet", "state-mlp"):
        rows = [json.loads(line) for line in (tmp_path / "runs" / name / "metrics.jsonl").open()]
        transitions = [row["env_transitions"] for row in rows]
        assert all(a < b for a, b in zip(transitions, transitions[1:])), name
        assert (tmp_path / "runs" / f"{name}-resumed.log").exists()


GUIDED = ["--action-space", "paddle", "--guide.coef", "10", "--guide.hold", "100000000",
          "--guide.until", "100000000", "--ppo.kl-stop", "off"]  # fmt: skip
"""The guided hour's flags (docs/results/ppo-easy-guided.json), forwarded to both runs."""


@pytest.mark.slow
@pytest.mark.timeout(1500)  # the script runs 10 minutes, then evaluates both policies
def test_a_short_guided_run_pushes_where_ppo_alone_does_not_yet(tmp_path: Path) -> None:
    """The guided hour's first 10 minutes (docs/results/ppo-easy-guided.json, `curve`):
    HAMnet's training success over the last 200 episodes read 0.09-0.275 (mean 0.21) between
    60 k and 110 k transitions, which it passed after 7.5 minutes beside the baseline; PPO
    alone read 0.015-0.04 there in the paddle hour (ppo-easy-paddle.json, `curve`), so a
    mean of at least 0.1 says the guide taught it, and fails if the labels, their transport
    or the imitation term break."""
    out = tmp_path / "result"
    subprocess.run([sys.executable, str(ROOT / "scripts" / "ppo_easy.py"), "--minutes", "10", "--eval-episodes", "32",
                    "--runs", str(tmp_path / "runs"), "--out", str(out), *GUIDED], check=True, timeout=1200)  # fmt: skip
    result = json.loads(out.with_suffix(".json").read_text())
    window = [row["success_rate"] for row in result["curve"]
              if 60_000 <= row["env_transitions"] < 110_000]  # fmt: skip
    assert window, "HAMnet did not reach 110 k transitions in 10 minutes"
    assert statistics.mean(window) >= 0.1
