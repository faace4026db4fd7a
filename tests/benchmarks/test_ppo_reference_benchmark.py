"""`benchmarks/ppo_reference.py`: the figures issue 27 names, from hand-made episodes whose
answer is known, and from a `--quick` run of both PPOs and the random policy to the end
(what the figures are worth belongs to the full run)."""

from __future__ import annotations

import argparse
import importlib
import math
from types import ModuleType

import numpy as np
import pytest

from tests.benchmarks.quick import BENCHMARKS, run_quick

pytest.importorskip("gymnasium", reason="the reference extra: pip install -e '.[reference]'")
pytest.importorskip(
    "stable_baselines3", reason="the reference extra: pip install -e '.[reference]'"
)

RANDOM_RETURN_SEED_0 = -42.72
"""Uniform random actions on Reacher-v5, seed 0, 1000 episodes (docs/results/
ppo-reference.json, `random_final_returns`); the quick run's 245 episodes are their start."""
ISSUE_FIGURES = (
    "ours_final_return",
    "reference_final_return",
    "random_return",
    "ours_vs_reference",
    "ours_final_returns",
    "reference_final_returns",
    "random_final_returns",
    "reference_package",
    "reference_version",
    "settings",
    "diagnostics",
    "command",
    "commit",
)


def benchmark(monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    """The benchmark script as a module (it imports `common` from benchmarks/, as a script)."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    return importlib.import_module("ppo_reference")


def figures(module: ModuleType, ours_late: float) -> dict:
    """`figures_of` for one seed of 1000 env steps: ours ends with returns -12 and
    `ours_late` after -40 early on, the reference with -5 after -30, random actions earn -44
    and -46. Only episodes ending in the last 10% (step > 900) count for the learners; every
    episode counts for random actions."""
    steps = 1000
    episodes = {
        "ours": [(100, -40.0), (950, -12.0), (1000, ours_late)],
        "reference": [(500, -30.0), (990, -5.0)],
        "random": [(50, -44.0), (100, -46.0)],
    }
    results = {
        name: [{"episodes": runs, "updates": [], "wall_clock_s": 0.0, "env_steps": steps}]
        for name, runs in episodes.items()
    }
    args = argparse.Namespace(quick=True, task="Reacher-v5", seeds=[0], ppo="standard")
    return module.figures_of(results, args, steps, {"commit": "abc", "uncommitted": []})


def test_ratio_is_the_share_of_the_reference_improvement_over_random(monkeypatch) -> None:
    """Recomputing `ours_vs_reference` from the figures it printed, with the benchmark's own
    formula, could not fail: here the answer is worked by hand (ours -10, reference -5,
    random -45: 35 / 40), so a wrong final-return window, a swapped run or a wrong
    normaliser fails, and the ratio must follow a change in our returns."""
    module = benchmark(monkeypatch)
    worse = figures(module, ours_late=-8.0)
    assert all(name in worse for name in ISSUE_FIGURES)
    assert worse["ours_final_return"] == pytest.approx(-10.0)
    assert worse["reference_final_return"] == pytest.approx(-5.0)
    assert worse["random_return"] == pytest.approx(-45.0)
    assert worse["ours_vs_reference"] == pytest.approx(35.0 / 40.0)
    level = figures(module, ours_late=2.0)  # ours now ends at -5, as the reference
    assert level["ours_vs_reference"] == pytest.approx(1.0)


@pytest.mark.slow
def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    """The real runs behind the figures: Reacher's rewards are never positive, random
    actions earn what 1000 episodes of them earned before, each summary is its seeds' mean
    and the ratio is the quotient of the returns printed beside it."""
    figures = run_quick("ppo_reference.py", timeout=600)
    assert figures["benchmark"] == "ppo_reference" and figures["mode"] == "quick"
    assert figures["task"] == "Reacher-v5" and figures["env_steps"] == 12_288
    assert figures["seeds"] == [0] and all(name in figures for name in ISSUE_FIGURES)
    assert figures["reference_package"] == "stable-baselines3" and figures["reference_version"]
    for name in ("ours", "reference", "random"):
        finals = figures[f"{name}_final_returns"]
        assert len(finals) == 1 and math.isfinite(finals[0]) and finals[0] < 0.0
    assert figures["ours_final_return"] == pytest.approx(np.mean(figures["ours_final_returns"]))
    assert figures["reference_final_return"] == pytest.approx(
        np.mean(figures["reference_final_returns"])
    )
    assert figures["random_return"] == pytest.approx(RANDOM_RETURN_SEED_0, abs=3.0)
    assert "every episode of 12288 steps" in figures["final_return"]
    gained = figures["ours_final_return"] - figures["random_return"]
    reference_gained = figures["reference_final_return"] - figures["random_return"]
    assert figures["ours_vs_reference"] == pytest.approx(gained / reference_gained)
    assert figures["command"].endswith("--quick") and figures["commit"]
