"""Faults of the recorder against real processes: a full disk, a restart, a failed auxiliary
service under `hamnet up`. Each must stay local: the control loop (the sim here) goes on,
the recording so far stays readable, nothing is overwritten, and no traceback is printed.
See docs/reliability.md for the table of faults these tests show.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.recordings import read_file
from hamnet.runtime.service import EXIT_NO_RESTART
from hamnet.runtime.transport import TransportConfig, open_session
from tests.conftest import transport_args
from tests.monitor.test_outputs import verified
from tests.stack.test_record_replay import Capture, stop, wait_until_recording
from tests.stack.test_up import by_label, write_stack
from tests.stack.up import alive, up

TMPFS_BYTES = 3 * 1024 * 1024
"""Size of the full disk: a few chunks of the test's 200 kB payloads."""


def user_namespace_tmpfs(mount_point: Path) -> list[str] | None:
    """A command prefix that runs its arguments with a tmpfs of `TMPFS_BYTES` mounted on
    `mount_point`, in a user and mount namespace of their own (no root needed where the
    kernel allows unprivileged user namespaces); None where it cannot be made here."""
    unshare = shutil.which("unshare")
    if unshare is None:
        return None
    mount = f"mount -t tmpfs -o size={TMPFS_BYTES} tmpfs {mount_point}"
    prefix = [unshare, "--user", "--map-root-user", "--mount", "sh", "-c", f'{mount} && exec "$@"', "sh"]
    probe = subprocess.run([*prefix, "true"], capture_output=True, check=False)
    return prefix if probe.returncode == 0 else None


def sim_steps(session, transport: TransportConfig) -> Inbox:
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("state", contract.topic("sim/<w>/state").key(transport.namespace, w="0"), RobotState)
    return inbox


def next_step(inbox: Inbox, after: int, timeout: float = 30.0) -> int:
    """The step of the first sim state above `after`; fails if none comes within `timeout`."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        received = inbox.get(timeout=0.2)
        if received is not None and received.value.header.step > after:
            return received.value.header.step
    raise AssertionError(f"no sim state after step {after} within {timeout} s")


def test_a_recorder_on_a_full_disk_stops_alone_and_keeps_what_it_wrote(tmp_path, transport):
    """The disk full of issue 13: the recorder died with tracebacks, spent its restarts in
    10 s, and the launcher then stopped the whole stack. Here a real tmpfs of 3 MiB fills
    up under a running stack; the recorder must log one error line, exit 74 (not
    restarted), leave a file that reads up to its last complete chunk with the messages
    published before the disk filled, and the sim must keep stepping.

    The tmpfs is mounted in a user and mount namespace (`unshare --user --map-root-user
    --mount`), which needs no root where the kernel allows unprivileged user namespaces;
    `hamnet up` runs inside it, the test outside reads the file through
    /proc/<launcher pid>/root. Where no such namespace can be made the test is skipped:
    /dev/full (tested below) fails the very first write, so it cannot show a file that
    fills up mid-recording.
    """
    disk = tmp_path / "disk"
    disk.mkdir()
    wrapper = user_namespace_tmpfs(disk)
    if wrapper is None:
        pytest.skip("no unprivileged user namespace here to mount a tmpfs in")
    stack = write_stack(tmp_path, f"""
services:
  sim: {{args: {{num-envs: 1, num-objects: 1, nthread: 1, realtime: true}}}}
  record: {{args: {{output: {disk}/run.mcap, chunk-s: 0.2}}}}
""")
    key = f"hamnet/{transport.namespace}/test/fill"
    # Zenoh's shared memory does not reach into another user namespace: large payloads go
    # over loopback TCP instead, for every process of the stack and the test alike.
    transport = replace(transport, shared_memory=False)
    session = open_session(transport)
    states = sim_steps(session, transport)
    try:
        with up(stack, transport, "--no-shared-memory", cwd=tmp_path, wrapper=wrapper) as run:
            run.wait_for(r"record/0 ready", timeout=60)
            wait_until_recording(session, transport, _Running(run))
            fill = Publisher(session, key, "test/0")
            payload = np.random.default_rng(0).bytes(200_000)  # incompressible
            recording = Path(f"/proc/{run.process.pid}/root") / disk.relative_to("/") / "run.mcap"
            index = 0
            while "stopped on a fault a restart cannot fix" not in run.output:
                assert index < 1000 and run.process.poll() is None, run.output
                fill.put_encoded(index.to_bytes(4, "little") + payload)
                index += 1
                time.sleep(0.02)  # paced so that Zenoh delivers them all; the disk fills anyway
            kept = tmp_path / "kept.mcap"
            shutil.copyfile(recording, kept)
            step = next_step(states, after=0)
            next_step(states, after=step)  # the sim steps on after the recorder stopped
            assert run.process.poll() is None, run.output
            stop(run.process)
        summary = run.summary()
    finally:
        session.close()
    processes = by_label(summary)
    assert summary["exit_code"] == 0, run.output
    assert processes["record/0"]["outcome"] == "failed" and not processes["record/0"]["critical"]
    assert processes["record/0"]["returncode"] == EXIT_NO_RESTART
    assert processes["record/0"]["restarts"] == 0
    assert processes["sim/0"]["outcome"] == "stopped"
    record_lines = [line for line in run.output.splitlines() if line.startswith("record/0")]
    errors = [line for line in record_lines if "ERROR" in line]
    assert len(errors) == 1 and "No space left on device" in errors[0], record_lines
    assert "Traceback" not in run.output
    numbers = [int.from_bytes(m.payload[:4], "little") for m in read_file(kept) if m.key == key]
    assert numbers and numbers == list(range(len(numbers))), numbers  # a prefix, in order
    assert len(numbers) * 200_000 > TMPFS_BYTES / 2  # the earlier chunks are all there


class _Running:
    """The launcher seen as the recorder process by `wait_until_recording` (it only polls)."""

    def __init__(self, run) -> None:
        self._run = run
        self.stdout = self

    def poll(self) -> int | None:
        return self._run.process.poll()

    def read(self) -> str:
        return self._run.output


def test_a_recorder_writing_to_dev_full_exits_74_with_one_line(spawn, transport, tmp_path):
    """Without a tmpfs, /dev/full gives ENOSPC on the first write: the recorder reports it
    in one line, without traceback, and exits 74 so that `hamnet up` does not restart it."""
    output = tmp_path / "full.mcap"
    output.symlink_to("/dev/full")
    recorder = spawn("record", "-o", str(output), *transport_args(transport))
    assert recorder.wait(timeout=60) == EXIT_NO_RESTART
    printed = recorder.stdout.read()
    assert "Traceback" not in printed
    errors = [line for line in printed.splitlines() if "ERROR" in line]
    assert len(errors) == 1 and "No space left on device" in errors[0], printed


def test_a_failed_auxiliary_service_leaves_the_stack_running(tmp_path, transport):
    """A recorder that cannot write (its output is /dev/full) fails at once and is not
    restarted; an auxiliary echo that keeps crashing spends its restarts; neither stops the
    stack, which ends at its duration with exit 0 and lists both as failed."""
    full = tmp_path / "full.mcap"
    full.symlink_to("/dev/full")
    bad_config = tmp_path / "bad.json5"
    bad_config.write_text("{ not json5")  # passes `--check` (the file exists), fails at start
    stack = write_stack(tmp_path, f"""
duration_s: 60
services:
  record: {{args: {{output: {full}}}}}
  flaky:
    command: echo
    critical: false
    args: {{zenoh-config: {bad_config}}}
    restart: {{max_restarts: 1, backoff_s: 0.05, backoff_max_s: 0.1}}
  watch: {{command: echo, workers: [w]}}
""")
    with up(stack, transport, cwd=tmp_path) as run:
        run.wait_for(r"flaky/0 failed \(exit 2\); it is auxiliary", timeout=60)
        run.wait_for(r"record/0 failed \(exit 74\); it is auxiliary", timeout=60)
        assert run.process.poll() is None, run.output
        watch = run.started()["watch/w"]
        assert len(watch) == 1 and alive(watch[0])
        stop(run.process)
    summary = run.summary()
    processes = by_label(summary)
    assert summary["exit_code"] == 0 and summary["ended"] == "stopped by a signal"
    assert processes["record/0"]["outcome"] == "failed" and processes["record/0"]["restarts"] == 0
    assert processes["flaky/0"]["outcome"] == "failed" and processes["flaky/0"]["restarts"] == 1
    assert processes["watch/w"]["outcome"] == "stopped"
    assert "auxiliary, failed while the stack went on: record/0 (exit 74), flaky/0 (exit 2)" in run.output


def test_a_critical_recorder_failing_stops_the_stack(tmp_path, transport):
    full = tmp_path / "full.mcap"
    full.symlink_to("/dev/full")
    stack = write_stack(tmp_path, f"""
services:
  record: {{critical: true, args: {{output: {full}}}}}
  watch: {{command: echo}}
""")
    with up(stack, transport, cwd=tmp_path) as run:
        assert run.wait(timeout=60) == 1, run.output
    assert run.summary()["ended"] == "record/0 crashed with no restarts left"


def test_a_restarted_recorder_leaves_two_readable_files_that_info_and_replay_read(
    spawn, transport, tmp_path
):
    """A restarted recorder used to overwrite its output (a 27 MB recording became 3 MB).
    Killed and started again on the same `--output`, it writes `run.1.mcap`; `record info`
    and `replay`, given `run.mcap`, read both parts in order."""
    ns, path = transport.namespace, tmp_path / "run.mcap"
    key = f"hamnet/{ns}/test/numbered"
    session = open_session(transport)
    try:
        numbered = Publisher(session, key, "test/0")
        for part in range(2):
            recorder = spawn("record", "-o", str(path), "--chunk-s", "0.2", *transport_args(transport))
            wait_until_recording(session, transport, recorder)
            for i in range(5):
                numbered.put_encoded(b"part %d message %d" % (part, i))
            time.sleep(1.0)  # past --chunk-s: the chunk is on disk before the kill
            stop(recorder, 9 if part == 0 else 15)
        parts = [path, tmp_path / "run.1.mcap"]
        assert set(tmp_path.glob("*.mcap")) == set(parts)
        written = [[m.payload for m in read_file(p) if m.key == key] for p in parts]
        assert written == [[b"part %d message %d" % (k, i) for i in range(5)] for k in range(2)]

        info = subprocess.run([sys.executable, "-m", "hamnet", "record", "info", str(path), "--json"],
                              capture_output=True, text=True, check=True)  # fmt: skip
        described = json.loads(info.stdout)
        assert [f["path"] for f in described["files"]] == [str(p) for p in parts]
        assert [t["messages"] for t in described["topics"] if t["key"] == key] == [10]

        into = f"{ns}r"
        replayed = Capture(session, f"hamnet/{into}/test/**")
        replay = spawn("replay", str(path), "--fast", "--start-delay-s", "1.5", "--namespace", into,
                       "--rendezvous", transport.rendezvous)  # fmt: skip
        assert replay.wait(timeout=60) == 0, replay.stdout.read()
        deadline = time.monotonic() + 10
        while len(replayed.per_key().get(f"hamnet/{into}/test/numbered", [])) < 10:
            assert time.monotonic() < deadline, replayed.per_key()
            time.sleep(0.1)
        assert replayed.per_key()[f"hamnet/{into}/test/numbered"] == written[0] + written[1]
    finally:
        session.close()


def test_restarts_under_the_launcher_never_replace_the_recording(tmp_path, transport):
    """Under `hamnet up`, a recorder and a monitor killed with SIGKILL are restarted and
    write the next part: the first ones stay as they were (the monitor's used to be cut to a
    fraction by its restart), the summary lists every file the run wrote, and the view the
    stack closed has Rerun's footer."""
    (tmp_path / "view.rrd").write_bytes(b"an earlier run's view")
    stack = write_stack(tmp_path, """
services:
  record: {args: {output: run.mcap, chunk-s: 0.2}}
  monitor: {args: {save: view.rrd}}
outputs: [run.mcap, view.rrd]
""")
    with up(stack, transport, cwd=tmp_path) as run:
        for label in ("record/0", "monitor/0"):
            run.wait_for(rf"{label} ready", timeout=60)
            os.kill(run.started()[label][0], 9)
            run.wait_for(rf"{label} ready", count=2, timeout=60)
        stop(run.process)
    assert sorted(p.name for p in tmp_path.glob("*.mcap")) == ["run.1.mcap", "run.mcap"]
    assert "run.mcap exists: recording to run.1.mcap" in run.output
    assert (tmp_path / "view.rrd").read_bytes() == b"an earlier run's view"
    assert sorted(p.name for p in tmp_path.glob("*.rrd")) == ["view.1.rrd", "view.2.rrd", "view.rrd"]
    assert verified(tmp_path / "view.2.rrd")  # closed by the stack's stop
    for name in ("run.mcap", "run.1.mcap", "view.1.rrd", "view.2.rrd"):
        assert f"written: {name} (" in run.output, run.output
    assert "written: view.rrd (" not in run.output  # an earlier run's, untouched
