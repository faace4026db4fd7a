"""The report of an evaluation as a JSON-able dict, and its `report.json`.

One policy: `{"per_domain": {suite: summary}, "overall": summary}`, one entry per suite
present (`procedural` and the benchmark domains, in `SUITES` order). Several policies
(checkpoints or architectures): `{"reference": label, "policies": {label: one policy's
report}, "differences": [...]}`, each policy against the first (`metrics.compare`). A
summary is `metrics.Summary` as a dict: episodes, successes, rate, ci_low, ci_high, reasons,
length_mean, length_median.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from hamnet.evaluation.metrics import OVERALL, compare, summarise_suites
from hamnet.evaluation.records import EpisodeRecord


def policy_report(records: Sequence[EpisodeRecord]) -> dict[str, Any]:
    """The report of one policy's episodes: per_domain (each suite present) and overall."""
    summaries = {
        suite: dataclasses.asdict(summary) for suite, summary in summarise_suites(records).items()
    }
    overall = summaries.pop(OVERALL)
    return {"per_domain": summaries, "overall": overall}


def comparison_report(policies: Mapping[str, Sequence[EpisodeRecord]]) -> dict[str, Any]:
    """The report of two or more labelled policies' episodes, the first the reference."""
    differences = compare({label: summarise_suites(records) for label, records in policies.items()})
    return {
        "reference": next(iter(policies)),
        "policies": {label: policy_report(records) for label, records in policies.items()},
        "differences": [dataclasses.asdict(difference) for difference in differences],
    }


def write_report(report: Mapping[str, Any], path: Path) -> Path:
    """Write `report` as indented JSON to `path` (e.g. RUN/report.json); returns `path`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report, indent=2) + "\n")
    return path
