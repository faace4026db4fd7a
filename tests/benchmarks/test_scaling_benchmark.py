"""benchmarks/scaling.py --quick runs and reports its figures (timings belong to the
benchmark, not to this test)."""

from __future__ import annotations

import pytest

from tests.benchmarks.quick import run_quick


@pytest.mark.slow
def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("scaling.py", timeout=240)
    assert figures["benchmark"] == "scaling" and set(figures["env_steps_per_s"]) == {"1", "2", "4"}
    assert figures["efficiency_2_workers"] > 0 and 0 < figures["learner_share"]["1"] < 1
    assert figures["tls_overhead"] is not None, figures["tls_note"]
