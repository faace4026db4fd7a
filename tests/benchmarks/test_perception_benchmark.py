"""`benchmarks/perception.py --quick` runs to the end and reports the figures its issue names."""

from __future__ import annotations

import pytest

from tests.benchmarks.quick import run_quick


@pytest.mark.slow
def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("perception.py", timeout=120)
    assert figures["num_envs"] == 64
    assert figures["culling_vs_union_speedup"] > 0 and figures["cache_speedup"] > 0
    assert figures["encoder_bfloat16_speedup"] > 0 and figures["local_shortlist_speedup"] > 0
    assert 0 <= figures["local_full_ranking_share"] < 1
    rows = (
        "cached_step",
        "uncached_step",
        "culling_sample_512",
        "cached_step_float32",
        "cached_step_bfloat16",
        "pushed_step_shortlist",
        "pushed_step_full_ranking",
    )
    for row in rows:
        assert 0 < figures[row]["median_ms"] <= figures[row]["p99_ms"], row
