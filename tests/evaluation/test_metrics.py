"""Success rates with Wilson intervals, per-suite summaries and the policy comparison."""

from __future__ import annotations

import pytest

from hamnet.evaluation.metrics import OVERALL, compare, summarise_suites, wilson_interval
from tests.evaluation.records import record


@pytest.mark.parametrize(
    "successes, expected",
    [(0, (0.0, 0.277533)), (5, (0.236593, 0.763407)), (10, (0.722467, 1.0))],
)
def test_wilson_interval_matches_the_formula(successes: int, expected: tuple) -> None:
    """Out of 10 episodes, against Wilson's formula worked by hand with z = 1.959964:
    centre (p + z^2/2n) / (1 + z^2/n), half-width z / (1 + z^2/n) sqrt(p(1-p)/n + z^2/4n^2).
    A normal (Wald) interval would give (0, 0) at 0/10 and (0.19, 0.81) at 5/10."""
    assert wilson_interval(successes, 10) == pytest.approx(expected, abs=1e-6)


def test_summaries_count_per_suite_and_overall() -> None:
    """Synthetic sink (2 of 4 succeed; one drop, one timeout) and procedural (1 of 2, one
    collision) episodes: each suite's and the overall counts, rates, reasons and lengths."""
    records = [
        record("sink", length=10),
        record("sink", length=20),
        record("sink", "drop", length=30),
        record("sink", "timeout", length=100),
        record("procedural", length=50),
        record("procedural", "collision", length=70),
    ]
    summaries = summarise_suites(records)
    assert list(summaries) == ["procedural", "sink", OVERALL]  # SUITES order, overall last
    sink = summaries["sink"]
    assert (sink.episodes, sink.successes, sink.rate) == (4, 2, 0.5)
    expected = {"timeout": 1, "drop": 1, "safety_stop": 0, "collision": 0, "torque_limit": 0}
    assert sink.reasons == expected
    assert (sink.length_mean, sink.length_median) == (40.0, 25.0)
    assert sink.ci_low < 0.5 < sink.ci_high
    overall = summaries[OVERALL]
    assert (overall.episodes, overall.successes) == (6, 3)
    assert overall.reasons["collision"] == 1 and overall.reasons["drop"] == 1


def test_compare_gives_differences_against_the_first_policy() -> None:
    """HAMnet 10/10 on sink and the MLP 0/10: a difference of -1 with disjoint intervals;
    on flat both 5/10: 0 and overlapping. Suites only one policy played are left out."""
    hamnet = [record("sink")] * 10 + [record("flat")] * 5 + [record("flat", "timeout")] * 5
    mlp = [record("sink", "drop")] * 10 + [record("flat")] * 5 + [record("flat", "drop")] * 5
    mlp += [record("grill")]
    differences = compare({"hamnet": summarise_suites(hamnet), "mlp": summarise_suites(mlp)})
    by_suite = {d.suite: d for d in differences}
    assert set(by_suite) == {"sink", "flat", OVERALL}
    assert all(d.policy == "mlp" and d.reference == "hamnet" for d in differences)
    assert by_suite["sink"].difference == -1.0 and not by_suite["sink"].intervals_overlap
    assert by_suite["flat"].difference == 0.0 and by_suite["flat"].intervals_overlap


def test_compare_needs_two_policies() -> None:
    with pytest.raises(ValueError):
        compare({"hamnet": summarise_suites([record("sink")])})
