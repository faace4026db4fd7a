"""benchmarks/training.py --quick runs and reports its figures (timings belong to the
benchmark, not to this test)."""

from __future__ import annotations

import pytest

from tests.benchmarks.quick import run_quick


@pytest.mark.slow
def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("training.py", timeout=120)
    assert figures["benchmark"] == "training" and figures["inprocess_env_steps_per_s"] > 0
    assert figures["inprocess_float32_env_steps_per_s"] > 0 and figures["precision_speedup"] > 0
    assert 0 < figures["inprocess_vs_physics_ceiling"] and set(figures["shares"]) >= {
        "sim",
        "perception",
        "policy",
        "safety",
        "learner",
    }
    seconds = figures["seconds_per_update"]
    for loop in ("overlapped", "sequential"):
        assert set(seconds[loop]) >= {"sim", "perception", "policy", "learner", "iteration"}
        assert 0 < seconds[loop]["sim"] < seconds[loop]["iteration"]
    assert all(0 < share <= 1.05 for share in figures["overlap_busy"].values())
    acting = figures["acting_env_steps_per_s"]
    assert set(acting) == {"inprocess", "float32", "sequential", "workers_1"}
    assert all(acting[name] > 0 and figures["update_s"][name] > 0 for name in acting)
    assert acting["inprocess"] > figures["inprocess_env_steps_per_s"]  # the update left out
    assert figures["workers_vs_inprocess_acting"] > 0
    assert figures["workers_vs_inprocess"] > 0 and figures["workers_1_env_steps_per_s"] > 0
    assert figures["workers_2_env_steps_per_s"] is None  # --quick measures one worker
    assert figures["workers_acting_while_learning_env_steps_per_s"] > 0
    assert figures["update_s"]["workers_acting_while_learning"] > 0
    assert figures["workers_acting_while_learning_vs_physics_ceiling"] > 0
    assert figures["services_vs_inprocess"] > 0 or figures["not_measured"]
