"""`benchmarks/transport.py --quick` runs to the end and reports the figures its issue names."""

from __future__ import annotations

from tests.benchmarks.quick import run_quick


def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("transport.py")
    assert figures["overhead_vs_raw_400k"] > -1 and figures["shm_speedup_4m"] > 0
    for setting in ("shm_on", "shm_off"):
        for path in ("runtime", "raw"):
            for size in ("1k", "400k", "4m"):
                measured = figures["results"][setting][path][size]
                assert measured["round_trip_median_us"] > 0 and measured["round_trip_p99_us"] > 0
    assert figures["results"]["shm_on"]["runtime"]["4m"]["via_shm"] > 0.5
