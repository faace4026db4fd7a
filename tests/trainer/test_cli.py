"""`hamnet trainer --inprocess` end to end at a tiny size, and `hamnet trainer plot` on its output."""

from __future__ import annotations

import json
from pathlib import Path

from hamnet.trainer.cli import main


def test_a_tiny_run_writes_metrics_checkpoint_summary_and_curves(tmp_path: Path) -> None:
    run = tmp_path / "run"
    args = ["--inprocess", "--sim.num-envs", "2", "--sim.num-objects", "2", "--sim.nthread", "1",
            "--sim.task.lambda-r", "0.3", "--steps-per-rollout", "2", "--max-env-transitions", "8",
            "--eval-episodes", "2", "--run-dir", str(run)]  # fmt: skip
    assert main(args) == 0
    summary = json.loads((run / "summary.json").read_text())
    assert summary["final_success_rate"] in (0.0, 0.5, 1.0) and summary["env_steps"] == 8
    assert isinstance(summary["final_goal_return"], float)
    assert summary["stage"] == "easy" and summary["stage_definition"]["task"]["success_radius"] == 0.1
    assert summary["stage_definition"]["task"]["lambda_r"] == 0.3  # a --sim.* flag over the stage
    assert summary["stage_definition"]["placement"]["start_keeps_goal_orientation"]
    assert len(summary["curve"]) == 2 and summary["seed"] == 0
    assert (run / "checkpoints" / "latest.safetensors").is_file()
    assert main(["plot", str(run)]) == 0
    assert (run / "curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_of_a_folder_without_metrics_says_so(tmp_path: Path, capsys) -> None:
    assert main(["plot", str(tmp_path)]) == 2
    assert "metrics.jsonl" in capsys.readouterr().out


def test_result_files_name_the_shipped_encoder_relative_to_the_repository(tmp_path: Path) -> None:
    """A summary (and the results written from it) must not name one machine's folders."""
    from hamnet.perception.checkpoint import SHIPPED_ENCODER
    from hamnet.trainer.results.summary import repository_path

    assert repository_path(SHIPPED_ENCODER) == "services/perception/weights/unicorn.safetensors"
    assert repository_path(tmp_path / "other.safetensors") == str(tmp_path / "other.safetensors")
