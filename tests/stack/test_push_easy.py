"""The shipped policy pushing (issue 28): `hamnet up compose/push-easy.yaml` serves the
easy-stage HAMnet shipped in the package (`easy-push`, in the paddle-twist action space,
through a safety service in the same space) on the easy stage, ends by itself, and its
summary gives the success rate of the episodes that ended, from the sim's own counts."""

from __future__ import annotations

import re
from pathlib import Path

from hamnet.launcher.stack import load
from hamnet.policy.shipped import read_card
from tests.stack.test_demo import isolated
from tests.stack.up import up

PUSH = Path(__file__).resolve().parents[2] / "compose" / "push-easy.yaml"


def test_the_shipped_policy_pushes_and_the_summary_gives_its_success_rate(tmp_path: Path) -> None:
    stack = load(PUSH)
    assert stack.services["policy"].args["checkpoint"] == "easy-push"
    assert stack.services["sim"].args["stage"] == "easy"
    card = read_card("easy-push")
    space = stack.services["safety"].args["safety.action-magnitude.space"]
    assert space == card["action_space"] == "paddle"  # else safety drops every action
    with up(PUSH, isolated(), cwd=tmp_path) as run:
        assert run.wait(timeout=150) == 0, run.output
    summary = run.summary()
    processes = {p["service"]: p for p in summary["processes"]}
    assert all(p["restarts"] == 0 for p in processes.values()), processes
    assert not processes["safety"]["drops"], processes["safety"]  # it took every action
    assert f"serving hamnet version {card['version']} on" in run.output  # the shipped weights
    events = processes["sim"]["events"]
    assert events["episodes_ended"] >= 16, events  # every environment ended an episode
    line = re.search(r"sim/0: (\d+) of (\d+) episodes that ended succeeded \(success rate ([\d.]+)\)",
                     run.output)  # fmt: skip
    assert line is not None, run.output[-3000:]
    assert int(line[2]) == events["episodes_ended"]
    assert int(line[1]) == events.get("episodes_succeeded", 0)
