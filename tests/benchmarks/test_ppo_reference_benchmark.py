"""`benchmarks/ppo_reference.py --quick` runs both PPOs and the random policy to the end and
reports the figures issue 27 names (what they are worth belongs to the full run)."""

from __future__ import annotations

import pytest

from tests.benchmarks.quick import run_quick

pytest.importorskip("gymnasium", reason="the reference extra: pip install -e '.[reference]'")
pytest.importorskip(
    "stable_baselines3", reason="the reference extra: pip install -e '.[reference]'"
)


@pytest.mark.slow
def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("ppo_reference.py", timeout=600)
    assert figures["benchmark"] == "ppo_reference" and figures["seeds"] == [0]
    assert figures["reference_package"] == "stable-baselines3" and figures["reference_version"]
    for name in ("ours", "reference", "random"):
        assert len(figures[f"{name}_final_returns"]) == 1
    ratio = (figures["ours_final_return"] - figures["random_return"]) / (
        figures["reference_final_return"] - figures["random_return"]
    )
    assert figures["ours_vs_reference"] == pytest.approx(ratio)
    assert figures["command"].endswith("--quick") and figures["commit"]
