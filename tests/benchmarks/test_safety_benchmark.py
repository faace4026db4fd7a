"""`benchmarks/safety.py --quick` runs to the end and reports the figures its issue names."""

from __future__ import annotations

from tests.benchmarks.quick import run_quick

STAGE_ROWS = (
    "1 guard",
    "2 scaling+magnitude",
    "3 cartesian clip",
    "4 ema",
    "5 joint limits",
    "7 torque pre-clip",
    "6 ruckig 80Hz (S=8)",
    "6 ruckig 1kHz (S=100)",
    "7 torque recheck 80Hz",
    "7 torque recheck 1kHz",
)


def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("safety.py", timeout=60)
    assert 0 < figures["fraction_of_policy_period_64"] and 0 < figures["fraction_of_1ms_1robot"]
    rows = {(row["num_envs"], row["row"]): row for row in figures["results"]}
    for num_envs in (1, 64):
        baselines = ("copy (baseline)", "raw ruckig 1kHz (baseline)", "whole pipeline 1kHz")
        for name in STAGE_ROWS + baselines:
            row = rows[(num_envs, name)]
            assert 0 < row["median_us"] <= row["p99_us"], (num_envs, name)
    whole = rows[(64, "whole pipeline 80Hz")]
    assert figures["fraction_of_policy_period_64"] == whole["fraction_of_policy_period"]
    assert figures["fraction_of_1ms_1robot"] == rows[(1, "whole pipeline 1kHz")]["fraction_of_1ms"]
