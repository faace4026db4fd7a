"""`benchmarks/monitor.py --quick` runs to the end and reports the figures it promises."""

from __future__ import annotations

from tests.benchmarks.quick import run_quick


def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("monitor.py", timeout=60)
    rows = {row["num_envs"]: row for row in figures["results"]}
    assert sorted(rows) == [4, 64] and figures["largest_num_envs"] == 64
    for row in rows.values():
        for name in ("parse only (baseline)", "skip", "decode", "draw"):
            assert 0 < row[name]["median_ms"] <= row[name]["p99_ms"], name
    assert figures["max_drawn_steps_per_s_4"] == 1e3 / rows[4]["draw"]["median_ms"]
    assert (
        figures["skip_vs_draw_largest"]
        == rows[64]["skip"]["median_ms"] / rows[64]["draw"]["median_ms"]
    )
