"""`hamnet bridge check`: the fake FR3 passes with a verdict and exit 0; a driver that is not
built is one line and exit 2; an impossible round-trip budget is a verdict of not ok, exit 1."""

from __future__ import annotations

from hamnet.cli import main


def test_the_fake_fr3_passes_the_check(capsys) -> None:
    assert main(["bridge", "check", "--driver", "fake", "--rounds", "5"]) == 0
    out = capsys.readouterr().out
    assert "round trip over 5 holds" in out and out.splitlines()[-1] == "verdict: ok"


def test_a_driver_not_built_is_one_line_and_exit_2(capsys) -> None:
    assert main(["bridge", "check"]) == 2
    assert capsys.readouterr().err.strip() == (
        "hamnet bridge: the franky driver is not built yet (issue #17): use --driver fake"
    )


def test_a_round_trip_over_budget_is_not_ok(capsys) -> None:
    args = ["--driver", "fake", "--rounds", "2", "--policy-period-s", "0.001",
            "--max-round-trip-fraction", "1e-9"]  # fmt: skip
    assert main(["bridge", "check", *args]) == 1
    assert capsys.readouterr().out.splitlines()[-1].startswith("verdict: NOT OK: round trip")
