"""`hamnet perception` start-up: weights are required before anything runs, so that a stack
file without them fails `hamnet up --check` instead of serving random tokens silently."""

from __future__ import annotations

import pytest

from hamnet.launcher.check import check
from hamnet.launcher.stack import parse
from hamnet.perception.cli import main


@pytest.mark.parametrize("argv", [[], ["--random-init", "--checkpoint", "encoder.safetensors"]])
def test_exactly_one_source_of_weights_is_required(argv, capfd) -> None:
    with pytest.raises(SystemExit) as exited:
        main(argv)
    assert exited.value.code == 2
    printed = " ".join("".join(capfd.readouterr()).replace("│", " ").split())  # unboxed
    assert "exactly one of --checkpoint PATH and --random-init" in printed


def test_stack_check_flags_a_perception_without_weights() -> None:
    stack = parse({"services": {
        "perception": {},
        "ok": {"command": "perception", "workers": [1], "args": {"random-init": True}},
    }}, "t")  # fmt: skip
    verdicts = {v.service: v.status for v in check(stack, {})}
    assert verdicts["ok"] == "ok"
    assert "exactly one of --checkpoint" in " ".join(verdicts["perception"].split())
