"""`benchmarks/recorder.py --quick` runs to the end and reports write, read and end-to-end
figures for every row."""

from __future__ import annotations

from tests.benchmarks.quick import run_quick


def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("recorder.py", timeout=120)
    rows = {(row["size_kb"], row["row"]): row for row in figures["results"]}
    for size_kb in (1, 100, 400):
        for name in ("file.write (baseline)", "write zstd", "write lz4", "write none", "read zstd"):
            row = rows[(size_kb, name)]
            assert row["mb_s"] > 0 and row["us_per_message"] > 0, (size_kb, name)
        assert 0 < rows[(size_kb, "write zstd")]["ratio"] < 1.1  # noise barely compresses
    assert figures["write_mb_s_400k_zstd"] == rows[(400, "write zstd")]["mb_s"]
    assert figures["baseline_mb_s_400k"] == rows[(400, "file.write (baseline)")]["mb_s"]
    assert set(figures["e2e_recorded_fraction"]) == {"10Hz", "50Hz"}
    for row in figures["end_to_end"]:
        assert row["published"] > 0 and 0 <= row["recorded"] <= row["published"]
