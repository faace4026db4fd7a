"""The README's first command: `hamnet up compose/demo.yaml` runs the whole loop (sim ->
perception -> policy -> safety -> sim, monitored and recorded), ends by itself, and says
which services are not built yet."""

from __future__ import annotations

from pathlib import Path

from mcap.reader import make_reader

from hamnet.cli import COMMANDS
from hamnet.launcher.stack import load
from hamnet.runtime import contract
from tests.stack.up import alive, up

DEMO = Path(__file__).resolve().parents[2] / "compose" / "demo.yaml"
LOOP = ("sim/<w>/state", "sim/<w>/scene", "perception/<w>/tokens", "policy/<w>/action",
        "safety/<w>/command", "sim/<w>/transition")  # fmt: skip
"""The topics of one turn of the control loop, all in the recording."""


def test_demo_closes_the_loop_records_it_and_lists_the_missing_services(tmp_path, transport):
    with up(DEMO, transport, "--duration-s", "12", cwd=tmp_path) as run:
        assert run.wait(timeout=60) == 0, run.output
    summary = run.summary()
    assert summary["ended"] == "duration of 12 s reached"
    commands = {c.name: c for c in COMMANDS}
    stack = load(DEMO)
    built = {name for name, spec in stack.services.items() if commands[spec.command].module}
    for name in set(stack.services) - built:
        issue = commands[stack.services[name].command].issue
        assert (f"{name} (issue #{issue})" if issue else name) in summary["not_built"]
    processes = {p["service"]: p for p in summary["processes"]}
    assert set(processes) == built
    assert all(p["announced"] >= 1 and p["restarts"] == 0 for p in processes.values()), processes
    assert not any(alive(pid) for p in processes.values() for pid in p["pids"])

    # The loop turned: every service in it answered the previous one, step after step.
    ns = transport.namespace
    key = lambda path: contract.topic(path).key(ns, w="0")  # noqa: E731
    steps = processes["sim"]["published"][key("sim/<w>/state")]
    assert steps >= 20, processes["sim"]
    assert processes["sim"]["received"]["command"] >= steps - 2
    for service, path in (("perception", "perception/<w>/tokens"), ("policy", "policy/<w>/action"),
                          ("safety", "safety/<w>/command")):  # fmt: skip
        assert processes[service]["published"][key(path)] >= steps - 3, processes[service]
    assert not processes["policy"]["drops"] and not processes["safety"]["drops"]

    declared = {path.replace("<namespace>", ns) for path in stack.outputs}
    assert set(summary["outputs"]) == declared and not summary["outputs_missing"]
    recording = next(tmp_path / path for path in declared if path.endswith(".mcap"))
    with recording.open("rb") as stream:
        channels = make_reader(stream).get_summary().channels.values()
    assert {key(path) for path in LOOP} <= {channel.topic for channel in channels}
