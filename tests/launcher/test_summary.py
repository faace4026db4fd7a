"""The end-of-run summary: health counters survive restarts, and the table says what ran,
what is missing and which files were written."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from hamnet.launcher.secure import Security
from hamnet.launcher.summary import ProcessReport, Report, output_files, output_state, render
from hamnet.launcher.watch import HealthBoard
from hamnet.proto.health_pb2 import DropCount, Health, ServiceState


def health(uptime_s: float, received: int, rate: float, state: int = ServiceState.RUNNING) -> Health:
    report = Health(service="echo", worker="0", state=state, uptime_s=uptime_s, loop_rate_hz=rate)
    report.received["stack"] = received
    report.published["hamnet/ns/echo/0/out"] = received // 2
    report.drops.append(DropCount(key="hamnet/ns/x", reason="decode", count=received // 10))
    report.events["loop_stalls"] = received // 10
    return report


def test_health_counters_add_up_over_restarts() -> None:
    """A restarted process starts counting from zero: the totals must add both runs, not
    keep only the latest report (a smaller uptime marks the restart)."""
    board = HealthBoard()
    for report in (health(1, 10, 10.0), health(2, 20, 12.0), health(0.5, 5, 8.0),
                   health(1.5, 30, 0.0, ServiceState.STOPPING)):
        board.add(report)
    totals = board.totals("echo", "0")
    assert totals.received == {"stack": 50}
    assert totals.published == {"hamnet/ns/echo/0/out": 25}
    assert totals.drops == {("hamnet/ns/x", "decode"): 5}
    assert totals.events == {"loop_stalls": 5}
    assert totals.loop_rate_hz == 10.0  # mean of the RUNNING reports only
    assert board.totals("echo", "1").received == {}


def test_output_files_lists_every_file_the_run_wrote_with_sizes(tmp_path: Path) -> None:
    """A file output stands for its sequence: the run's new part (`a.1.mcap`, written after
    an earlier run's `a.mcap`) is listed, the untouched earlier part is not; a monitor's
    `v.rrd` left as it was and written to `v.1.rrd` likewise; folders by their size."""
    (tmp_path / "a.mcap").write_bytes(b"x" * 10)
    (tmp_path / "v.rrd").write_bytes(b"x" * 3)
    paths = (tmp_path / "a.mcap", tmp_path / "ckpt", tmp_path / "v.rrd", tmp_path / "absent.rrd")
    before = output_state(paths)
    (tmp_path / "a.1.mcap").write_bytes(b"x" * 7)
    (tmp_path / "v.1.rrd").write_bytes(b"x" * 4)
    (tmp_path / "ckpt").mkdir()
    (tmp_path / "ckpt" / "1.safetensors").write_bytes(b"x" * 5)
    assert output_files(paths, before) == (
        {str(tmp_path / "a.1.mcap"): 7, str(tmp_path / "ckpt"): 5, str(tmp_path / "v.1.rrd"): 4},
        [str(tmp_path / "absent.rrd")],
    )


def test_render_shows_processes_missing_services_and_outputs() -> None:
    process = ProcessReport(
        service="watch", worker="0", command="echo", critical=True, outcome="stopped", exit="exit 0",
        returncode=0, restarts=1, uptime_s=4.2, ready_s=0.3, announced=2, pids=[11, 12],
        received={"stack": 12}, published={}, drops={"hamnet/ns/x: decode": 3},
        events={"loop_stalls": 2}, loop_rate_hz=9.87,
    )
    report = Report(
        stack="demo", namespace="demo", ended="duration of 5 s reached", exit_code=0,
        elapsed_s=5.5, processes=[process], not_built="sim (issue #3), trainer",
        outputs={"runs/demo/stack.mcap": 3 * 1024 * 1024}, outputs_missing=["runs/demo/monitor.rrd"],
        security=Security("certs", "compose/secure/router.json5", "tls/127.0.0.1:7447"),
    )
    lines = render(report).splitlines()
    assert lines[0] == "stack demo (namespace demo): duration of 5 s reached after 5.5 s; exit status 0"
    assert lines[1] == ("secure: mutual TLS (certificates in certs), access control by "
                        "compose/secure/router.json5 on the stack's router at tls/127.0.0.1:7447")  # fmt: skip
    assert lines[2].split() == ["PROCESS", "COMMAND", "OUTCOME", "EXIT", "RESTARTS", "UPTIME",
                                "READY", "RECEIVED", "PUBLISHED", "DROPS", "LOOP"]
    assert lines[3].split() == ["watch/0", "echo", "stopped", "exit", "0", "1", "4.2", "s", "0.3",
                                "s", "12", "0", "3", "9.9", "Hz"]
    assert lines[4:] == [
        "  watch/0 dropped 3 on hamnet/ns/x: decode",
        "  watch/0: 2 loop stalls",
        "not built yet: sim (issue #3), trainer",
        "written: runs/demo/stack.mcap (3.0 MiB)",
        "not written: runs/demo/monitor.rrd",
    ]
    document = json.loads(report.to_json())
    assert document["processes"][0]["pids"] == [11, 12]
    assert document["security"] == {"tls_dir": "certs", "access": "compose/secure/router.json5",
                                    "router": "tls/127.0.0.1:7447"}  # fmt: skip


def test_the_summary_says_when_a_stack_is_not_secure() -> None:
    """A stack on plain links says so, and TLS without the stack's own router says whose
    rules apply: a user sees which one ran."""
    report = Report(stack="demo", namespace="demo", ended="stopped by a signal", exit_code=0,
                    elapsed_s=1.0, processes=[], not_built="", outputs={}, outputs_missing=[])  # fmt: skip
    assert render(report).splitlines()[1].startswith("not secure: plain links, no access control")
    assert json.loads(report.to_json())["security"] == {"tls_dir": None, "access": None, "router": None}
    assert Security("certs").text().startswith("mutual TLS (certificates in certs); no access control")


def test_the_summary_prints_the_success_rate_of_the_episodes_that_ended() -> None:
    """The sim counts ended and successful episodes in its health reports: the summary
    turns them into a rate (a process without episodes prints none)."""
    sim = ProcessReport(
        service="sim", worker="0", command="sim", critical=True, outcome="stopped", exit="exit 0",
        returncode=0, restarts=0, uptime_s=30.0, ready_s=1.0, announced=1, pids=[7], received={},
        published={}, drops={}, events={"episodes_ended": 12, "episodes_succeeded": 5},
        loop_rate_hz=20.0,
    )  # fmt: skip
    report = Report(stack="push-easy", namespace="push", ended="duration of 30 s reached",
                    exit_code=0, elapsed_s=30.0, processes=[sim], not_built="", outputs={},
                    outputs_missing=[])  # fmt: skip
    lines = render(report).splitlines()
    assert "sim/0: 5 of 12 episodes that ended succeeded (success rate 0.42)" in lines
    assert not any("succeeded (" in line for line in render(dataclasses.replace(
        report, processes=[dataclasses.replace(sim, events={})])).splitlines())  # fmt: skip
