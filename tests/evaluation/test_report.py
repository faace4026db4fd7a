"""The report dict, report.json and the PNG figure."""

from __future__ import annotations

import json

import matplotlib.image

from hamnet.evaluation.figure import plot_evaluation
from hamnet.evaluation.records import BENCHMARK_DOMAINS, PROCEDURAL
from hamnet.evaluation.report import comparison_report, policy_report, write_report
from tests.evaluation.records import record


def every_suite() -> list:
    """Two episodes per suite, one success and one timeout, procedural and the nine domains."""
    suites = (PROCEDURAL, *BENCHMARK_DOMAINS)
    return [record(suite, reason) for suite in suites for reason in ("success", "timeout")]


def test_report_has_one_entry_per_suite_present() -> None:
    """Nine domains and procedural played: ten per_domain entries in order, and overall."""
    report = policy_report(every_suite())
    assert list(report["per_domain"]) == [PROCEDURAL, *BENCHMARK_DOMAINS]
    assert report["overall"]["episodes"] == 20 and report["overall"]["successes"] == 10
    assert policy_report([record("sink")])["per_domain"].keys() == {"sink"}


def test_comparison_report_holds_each_policy_and_the_differences(tmp_path) -> None:
    """Two policies: both reports, the first as reference, a difference per shared suite and
    overall; the written report.json reads back equal."""
    report = comparison_report({"hamnet": every_suite(), "mlp": [record("sink", "drop")]})
    assert report["reference"] == "hamnet"
    assert list(report["policies"]) == ["hamnet", "mlp"]
    assert [d["suite"] for d in report["differences"]] == ["sink", "overall"]
    assert report["differences"][0]["difference"] == -0.5
    path = write_report(report, tmp_path / "report.json")
    assert json.loads(path.read_text()) == report


def test_figure_is_a_valid_png(tmp_path) -> None:
    """One and two policies: the file is a PNG that decodes to a non-empty RGB(A) image."""
    for policies in ({"hamnet": every_suite()}, {"hamnet": every_suite(), "mlp": every_suite()}):
        out = plot_evaluation(policies, tmp_path / f"{len(policies)}.png", "test")
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        image = matplotlib.image.imread(out)
        assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
