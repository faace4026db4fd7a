"""Success rates with 95% confidence intervals, failure reasons and episode lengths, per
suite and overall, and the comparison of labelled policies; pure functions on
`EpisodeRecord` lists.

The interval is Wilson's score interval: unlike the normal approximation it stays inside
[0, 1] and keeps its coverage at 0 or n successes and at the few dozen episodes a quick
evaluation plays (Brown, Cai & DasGupta 2001, "Interval Estimation for a Binomial
Proportion", which recommends it for small n).
"""

from __future__ import annotations

import statistics
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from scipy.stats import binomtest

from hamnet.evaluation.records import FAILURE_REASONS, SUITES, EpisodeRecord

CONFIDENCE = 0.95
"""Confidence level of every interval (the issue asks for 95%)."""

OVERALL = "overall"
"""The key of the summary over every suite."""


def wilson_interval(successes: int, episodes: int) -> tuple[float, float]:
    """The `CONFIDENCE` Wilson score interval of a success rate.

    Args:
        successes: episodes that succeeded, 0 <= successes <= episodes.
        episodes: episodes played, >= 1.
    Returns:
        (low, high), both in [0, 1].
    """
    interval = binomtest(successes, episodes).proportion_ci(CONFIDENCE, method="wilson")
    return float(interval.low), float(interval.high)


@dataclass(frozen=True)
class Summary:
    """Success, failures and lengths of a set of episodes."""

    episodes: int
    """Episodes played."""
    successes: int
    """Episodes that reached the goal."""
    rate: float
    """successes / episodes."""
    ci_low: float
    """Lower end of the `CONFIDENCE` Wilson interval of `rate`."""
    ci_high: float
    """Upper end of the `CONFIDENCE` Wilson interval of `rate`."""
    reasons: dict[str, int]
    """Failed episodes per reason, every one of `FAILURE_REASONS` (0 when none)."""
    length_mean: float
    """Mean episode length, policy steps."""
    length_median: float
    """Median episode length, policy steps."""


def summarise(records: Sequence[EpisodeRecord]) -> Summary:
    """The `Summary` of `records` (at least one)."""
    if not records:
        raise ValueError("no episodes to summarise")
    successes = sum(record.success for record in records)
    low, high = wilson_interval(successes, len(records))
    counts = Counter(record.reason for record in records)
    lengths = [record.length for record in records]
    return Summary(
        episodes=len(records),
        successes=successes,
        rate=successes / len(records),
        ci_low=low,
        ci_high=high,
        reasons={reason: counts[reason] for reason in FAILURE_REASONS},
        length_mean=statistics.fmean(lengths),
        length_median=float(statistics.median(lengths)),
    )


def summarise_suites(records: Sequence[EpisodeRecord]) -> dict[str, Summary]:
    """One `Summary` per suite present in `records`, in `SUITES` order, then `OVERALL`."""
    present = [suite for suite in SUITES if any(record.suite == suite for record in records)]
    summaries = {
        suite: summarise([record for record in records if record.suite == suite])
        for suite in present
    }
    return {**summaries, OVERALL: summarise(records)}


@dataclass(frozen=True)
class Difference:
    """One policy against the reference policy on one suite."""

    suite: str
    """A suite, or `OVERALL`."""
    policy: str
    """The policy's label."""
    reference: str
    """The reference policy's label (the first one compared)."""
    difference: float
    """policy's success rate minus the reference's."""
    intervals_overlap: bool
    """Whether the two 95% intervals overlap. Disjoint intervals mean a difference at the 5%
    level or better; overlapping ones do not prove the rates equal (the check is
    conservative, Schenker & Gentleman 2001, "On judging the significance of differences by
    examining the overlap between confidence intervals")."""


def compare(policies: Mapping[str, Mapping[str, Summary]]) -> list[Difference]:
    """Every policy after the first against the first, on each suite both played.

    Args:
        policies: label -> `summarise_suites` output, two or more; the first is the
            reference (HAMnet against the MLP baseline, as in the paper's Fig. r2s-result).
    Returns:
        One `Difference` per (policy, suite), in the policies' and the suites' order.
    """
    if len(policies) < 2:
        raise ValueError("a comparison needs two or more policies")
    (reference, base), *others = policies.items()
    return [
        Difference(
            suite=suite,
            policy=label,
            reference=reference,
            difference=summary.rate - base[suite].rate,
            intervals_overlap=summary.ci_low <= base[suite].ci_high
            and base[suite].ci_low <= summary.ci_high,
        )
        for label, summaries in others
        for suite, summary in summaries.items()
        if suite in base
    ]
