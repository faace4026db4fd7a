"""The evaluation's PNG: success rate per suite with its 95% interval, and why episodes failed.

Top: one bar per suite (and overall) per policy, side by side when policies are compared,
as the paper's benchmark figure sets HAMnet (blue) beside the MLP (orange) (App. Fig.
r2s-result); the error bars are the Wilson intervals of `metrics.summarise`. Bottom: per
suite and policy, the share of episodes that failed for each of `FAILURE_REASONS`, stacked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display on an evaluation machine
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes

from hamnet.evaluation.metrics import OVERALL, Summary, summarise_suites
from hamnet.evaluation.records import FAILURE_REASONS, EpisodeRecord
from hamnet.trainer.results.plot import save_figure

GROUP_WIDTH = 0.8
"""Share of each suite's slot on the x-axis taken by its bars (the rest separates suites)."""

REASON_COLOURS = {
    "timeout": "#9e9e9e",
    "drop": "#d62728",
    "safety_stop": "#9467bd",
    "collision": "#ff7f0e",
    "torque_limit": "#8c564b",
}
"""Colour of each failure reason in the stacked bars."""

POLICY_HATCHES = ("", "//", "..", "xx", "\\\\", "++")
"""Hatch of each policy's stacked bars, in order, so policies stay apart without colour."""


def _columns(summaries: Mapping[str, Mapping[str, Summary]]) -> list[str]:
    """Every suite some policy played, in the policies' order, `OVERALL` last."""
    columns: list[str] = []
    for per_suite in summaries.values():
        columns += [suite for suite in per_suite if suite not in columns and suite != OVERALL]
    return [*columns, OVERALL]


def _placed(
    per_suite: Mapping[str, Summary], columns: list[str], index: int, count: int
) -> tuple[np.ndarray, list[Summary]]:
    """x (S,) of the bars of policy `index` of `count`, and the summaries they show (the
    suites that policy played), side by side within each suite's slot."""
    slots = np.flatnonzero([suite in per_suite for suite in columns])  # (S,)
    offset = (index - (count - 1) / 2) * GROUP_WIDTH / count
    return slots + offset, [per_suite[columns[slot]] for slot in slots]


def _success_panel(
    axis: Axes, summaries: Mapping[str, Mapping[str, Summary]], columns: list[str]
) -> None:
    """Grouped bars of success rate with asymmetric Wilson error bars."""
    width = GROUP_WIDTH / len(summaries)
    for index, (label, per_suite) in enumerate(summaries.items()):
        x, shown = _placed(per_suite, columns, index, len(summaries))
        rate = np.array([s.rate for s in shown])  # (S,)
        errors = np.array([[s.rate - s.ci_low for s in shown], [s.ci_high - s.rate for s in shown]])
        axis.bar(x, rate, width, yerr=errors, capsize=2, label=label, color=f"C{index}")
    axis.set_ylim(0, 1)
    axis.set_ylabel("success rate (95% Wilson CI)")
    axis.grid(axis="y", alpha=0.3)
    axis.legend(fontsize=8)


def _reason_panel(
    axis: Axes, summaries: Mapping[str, Mapping[str, Summary]], columns: list[str]
) -> None:
    """Per suite and policy, the share of episodes failed per reason, stacked."""
    width = GROUP_WIDTH / len(summaries)
    for index, per_suite in enumerate(summaries.values()):
        x, shown = _placed(per_suite, columns, index, len(summaries))
        bottom = np.zeros(len(shown))  # (S,)
        for reason in FAILURE_REASONS:
            share = np.array([s.reasons[reason] / s.episodes for s in shown])  # (S,)
            axis.bar(
                x,
                share,
                width,
                bottom=bottom,
                color=REASON_COLOURS[reason],
                hatch=POLICY_HATCHES[index % len(POLICY_HATCHES)],
                edgecolor="white",
                label=reason if index == 0 else None,
            )
            bottom += share
    axis.set_ylim(0, 1)
    axis.set_ylabel("share of episodes failed")
    axis.grid(axis="y", alpha=0.3)
    axis.legend(fontsize=8, ncols=len(FAILURE_REASONS))


def plot_evaluation(policies: Mapping[str, Sequence[EpisodeRecord]], out: Path, title: str) -> Path:
    """Write the figure of one or more labelled policies' episodes to `out` (PNG).

    Args:
        policies: label -> that policy's records; one entry for a plain evaluation.
        out: the PNG to write (its folder is made).
        title: the figure's title (the checkpoint, or what is compared).
    Returns:
        `out`.
    """
    summaries = {label: summarise_suites(records) for label, records in policies.items()}
    columns = _columns(summaries)
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(max(8.0, 1.1 * len(columns)), 8))
    _success_panel(top, summaries, columns)
    _reason_panel(bottom, summaries, columns)
    for axis in (top, bottom):
        axis.set_xticks(range(len(columns)), columns, rotation=30, ha="right")
    hatches = ", ".join(
        f"{label}: {POLICY_HATCHES[i % len(POLICY_HATCHES)] or 'plain'}"
        for i, label in enumerate(summaries)
    )
    bottom.set_title(f"failure reasons ({hatches})" if len(summaries) > 1 else "failure reasons")
    top.set_title("success rate per suite")
    figure.suptitle(title)
    return save_figure(figure, out)
