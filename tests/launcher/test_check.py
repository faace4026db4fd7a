"""`hamnet up --check`: commands exist, built commands accept their arguments, services not
built yet are reported as missing rather than as errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from hamnet.cli import COMMANDS, Subcommand
from hamnet.launcher import check as check_module
from hamnet.launcher.check import check, not_built
from hamnet.launcher.cli import main
from hamnet.launcher.stack import parse


def verdicts(services: dict, forward: dict | None = None) -> dict[str, str]:
    stack = parse({"services": services}, "t")
    return {v.service: v.status for v in check(stack, forward or {})}


def test_built_command_with_valid_args_is_ok() -> None:
    assert verdicts({"watch": {"command": "echo", "args": {"period-s": 5, "reflect": True}}}) == {
        "watch": "ok"
    }


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            {"period-s": "fast"},
            "error: hamnet echo: --period-s: could not convert string to float: 'fast'",
        ),
        ({"perod-s": 1}, "error: hamnet echo: Unrecognized options: --perod-s"),
        ({"shm-pool-mb": 0}, "error: hamnet echo: shm_pool_mb must be > 0"),
    ],
)
def test_bad_args_of_a_built_command_name_the_flag(args: dict, expected: str) -> None:
    assert verdicts({"watch": {"command": "echo", "args": args}})["watch"].startswith(expected)


def test_forwarded_options_are_validated_too() -> None:
    status = verdicts({"echo": {}}, {"mode": "satellite"})["echo"]
    assert status.startswith("error:") and "--mode" in status


def test_unknown_command_is_an_error_listing_the_commands() -> None:
    status = verdicts({"simm": {}})["simm"]
    assert status.startswith("error: unknown command 'simm' (hamnet commands: sim, bridge,")


def test_a_stack_cannot_run_the_launcher() -> None:
    assert verdicts({"up": {}})["up"] == "error: a stack cannot run `hamnet up`"


def test_commands_not_built_yet_are_missing_not_errors(monkeypatch) -> None:
    """A stack naming a command whose service is not built is reported, not rejected; the
    registry is patched so that this holds whatever is built by now."""
    unbuilt = (
        Subcommand("perception", "clouds", None, 6),
        Subcommand("bridge", "robot", None),
    )
    registry = tuple(c for c in COMMANDS if c.name not in ("perception", "bridge")) + unbuilt
    monkeypatch.setattr(check_module, "COMMANDS", registry)
    stack = parse(
        {
            "services": {
                "perception": {"args": {"anything": 1}},
                "robot": {"command": "bridge"},
                "echo": {},
            }
        },
        "t",
    )
    result = check(stack, {})
    assert [v.status for v in result] == [
        "not validated: not built yet (issue #6)",
        "not validated: not built yet",
        "ok",
    ]
    assert not_built(result) == "perception (issue #6), robot: hamnet bridge"


def test_check_exits_2_and_names_the_problem(tmp_path: Path, capsys) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("services: {watch: {command: echo, args: {period-s: fast}}}")
    assert main(["--check", str(path)]) == 2
    out = capsys.readouterr().out
    assert "watch  hamnet echo [0]  critical   error: hamnet echo: --period-s" in out
    assert out.rstrip().endswith("1 of 1 services cannot run as written")


def test_check_of_a_file_with_an_unknown_key_exits_2(tmp_path: Path, capsys) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("services: {echo: {}}\nuntill: echo\n")
    assert main(["--check", str(path)]) == 2
    assert "untill: unknown key (did you mean 'until'?)" in capsys.readouterr().err


def test_a_value_a_command_refuses_is_one_line_for_check_and_up(tmp_path: Path, capsys) -> None:
    """`num-envs: -1` printed a traceback from the sim's config (issue 13)."""
    path = tmp_path / "bad.yaml"
    path.write_text("services: {sim: {args: {num-envs: -1}}}")
    assert main(["--check", str(path)]) == 2
    assert "sim  hamnet sim [0]  critical   error: " in capsys.readouterr().out
    assert main([str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"hamnet up: {path}: service sim: ") and "\n" not in err


def test_a_negative_duration_is_refused(tmp_path: Path, capsys) -> None:
    """`hamnet up --duration-s -5` started the stack and stopped it at once with exit 0."""
    path = tmp_path / "ok.yaml"
    path.write_text("services: {echo: {}}")
    with pytest.raises(SystemExit) as exited:
        main([str(path), "--duration-s", "-5"])
    assert exited.value.code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "hamnet up: --duration-s must be a positive number of seconds, got -5.0"
    ]


def test_a_remap_is_checked_against_the_commands_ports() -> None:
    found = verdicts({
        "shadow": {"command": "policy", "args": {"random-init": "mlp"},
                   "remap": {"state": "hamnet/other/sim/0/state"}},
        "typo": {"command": "policy", "workers": [1], "args": {"random-init": "mlp"},
                 "remap": {"stat": "sim/0/state"}},
        "wrong": {"command": "policy", "workers": [2], "args": {"random-init": "mlp"},
                  "remap": {"state": "sim/0/scene"}},
        "none": {"command": "echo", "remap": {"state": "sim/0/state"}},
    })  # fmt: skip
    assert found["shadow"] == "ok"
    assert found["typo"].startswith("error: no port 'stat'; the ports are state, tokens")
    assert "is not one of its keys" in found["wrong"]
    assert found["none"] == "error: this command has no ports to --remap"
