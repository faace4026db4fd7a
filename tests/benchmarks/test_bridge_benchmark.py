"""`benchmarks/bridge.py --quick` runs to the end and reports the figures its issue names
(timings belong to the benchmark, not to this test)."""

from __future__ import annotations

import pytest

from tests.benchmarks.quick import run_quick


@pytest.mark.slow
def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("bridge.py", timeout=180)
    assert figures["benchmark"] == "bridge" and figures["measured_states"] == 100
    assert 0 < figures["median_latency_ms"] <= figures["p99_latency_ms"]
    assert figures["p99_latency_fraction_of_period"] == pytest.approx(
        figures["p99_latency_ms"] / 100, abs=1e-3
    )
    assert figures["reflexes"] == 0
    assert 0 < figures["baseline_median_latency_ms"] <= figures["baseline_p99_latency_ms"]
