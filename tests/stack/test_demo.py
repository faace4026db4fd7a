"""The README's first command: `hamnet up compose/demo.yaml` runs what is built, ends by
itself, and says which services are not built yet."""

from __future__ import annotations

from pathlib import Path

from hamnet.cli import COMMANDS
from hamnet.launcher.stack import load
from tests.stack.up import alive, up

DEMO = Path(__file__).resolve().parents[2] / "compose" / "demo.yaml"


def test_demo_runs_what_is_built_and_lists_the_missing_services(tmp_path, transport):
    with up(DEMO, transport, "--duration-s", "5", cwd=tmp_path) as run:
        assert run.wait(timeout=30) == 0, run.output
    summary = run.summary()
    assert summary["ended"] == "duration of 5 s reached"
    commands = {c.name: c for c in COMMANDS}
    stack = load(DEMO)
    for name, spec in stack.services.items():
        command = commands[spec.command]
        if command.module is None:
            issue = f" (issue #{command.issue})" if command.issue else ""
            assert f"{name}{issue}" in summary["not_built"]
    assert "not built yet: perception (issue #6)" in run.output
    ran = {p["service"] for p in summary["processes"]}
    assert {"sim", "watch"} <= ran
    assert all(p["announced"] >= 1 and p["restarts"] == 0 for p in summary["processes"])
    assert not any(alive(pid) for p in summary["processes"] for pid in p["pids"])
    declared = {path.replace("<namespace>", transport.namespace) for path in stack.outputs}
    assert set(summary["outputs"]) | set(summary["outputs_missing"]) == declared
