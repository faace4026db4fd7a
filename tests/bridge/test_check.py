"""`hamnet bridge check`: the fake FR3 passes with a verdict and exit 0; a franky driver with no
reachable robot is not ok, exit 1; an impossible round-trip budget is a verdict of not ok, exit 1."""

from __future__ import annotations

from hamnet.cli import main


def test_the_fake_fr3_passes_the_check(capsys) -> None:
    """Round trips bounded by the whole period: the default 10% took 12.7 ms once on a loaded
    machine (the bound itself is tested in test_franky.py)."""
    argv = ["bridge", "check", "--driver", "fake", "--rounds", "5", "--max-round-trip-fraction", "1"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "round trip over 5 holds" in out and out.splitlines()[-1] == "verdict: ok"


def test_no_robot_at_the_address_is_not_ok(capsys) -> None:
    args = ["--franky.host", "127.0.0.9", "--franky.realtime", "ignore"]  # nothing listens there
    assert main(["bridge", "check", *args]) == 1
    verdict = capsys.readouterr().out.splitlines()[-1]
    assert verdict.startswith(
        "verdict: NOT OK: cannot connect: cannot reach the robot at 127.0.0.9"
    )


def test_a_round_trip_over_budget_is_not_ok(capsys) -> None:
    args = ["--driver", "fake", "--rounds", "2", "--policy-period-s", "0.001",
            "--max-round-trip-fraction", "1e-9"]  # fmt: skip
    assert main(["bridge", "check", *args]) == 1
    assert capsys.readouterr().out.splitlines()[-1].startswith("verdict: NOT OK: round trip")
