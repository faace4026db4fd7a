"""`benchmarks/policy.py --quick` runs to the end and reports the figures its issue names."""

from __future__ import annotations

import pytest

from hamnet.policy.registry import ARCHITECTURES
from tests.benchmarks.quick import run_quick


@pytest.mark.slow
def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("policy.py", timeout=120)
    rows = {(row["architecture"], row["batch"]): row for row in figures["results"]}
    names = [*ARCHITECTURES, "mlp-paper-widths"]
    assert set(rows) == {(name, batch) for name in names for batch in (64, 1024)}
    for row in rows.values():
        assert (
            0 < row["infer_ms"] <= row["infer_p99_ms"]
            and 0 < row["train_ms"] <= row["train_p99_ms"]
        )
    assert rows[("mlp", 1024)]["train_vs_mlp"] == 1.0
    assert figures["hamnet_vs_mlp_train"] == rows[("hamnet", 1024)]["train_vs_mlp"]
    assert figures["hamnet_vs_mlp_infer"] == rows[("hamnet", 1024)]["infer_vs_mlp"]
    paper_widths = rows[("hamnet", 1024)]["train_ms"] / rows[("mlp-paper-widths", 1024)]["train_ms"]
    assert figures["hamnet_vs_paper_width_mlp_train"] == paper_widths
