"""`hamnet record` and `hamnet replay` as processes on real Zenoh: a short real sim run is
recorded and replayed into another namespace, and what the replay publishes is compared
with the recording, byte for byte and in order per key; stepped replay advances one step
per stdin line; a recorder killed with SIGKILL leaves a file the standard MCAP reader reads
up to its last chunk."""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import threading
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import zenoh
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader

from hamnet.proto.health_pb2 import Health
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.recordings import read_file
from hamnet.runtime.tensor import to_tensor
from hamnet.runtime.transport import TransportConfig, open_session
from tests.conftest import transport_args
from tests.recorder.recordings import NS, STATE, T0, lock_step, state, write
from tests.recorder.test_scenes import scene

STEPS = 12
BURST = 300


class Capture:
    """Every sample on a key expression, in arrival order, taken in the Zenoh callback."""

    def __init__(self, session, key_expr: str) -> None:
        self.samples: list[tuple[str, bytes]] = []
        self._lock = threading.Lock()
        self._subscriber = session.declare_subscriber(key_expr, self._on_sample)

    def _on_sample(self, sample) -> None:
        with self._lock:
            self.samples.append((str(sample.key_expr), sample.payload.to_bytes()))

    def per_key(self, exclude: str = "\x00") -> dict[str, list[bytes]]:
        with self._lock:
            grouped = defaultdict(list)
            for key, payload in self.samples:
                if exclude not in key:
                    grouped[key].append(payload)
            return dict(grouped)

    def count(self, exclude: str) -> int:
        return sum(len(v) for v in self.per_key(exclude).values())


def wait_until_recording(session, transport: TransportConfig, recorder) -> None:
    """Publish probes on a key outside the contract until the recorder's Health says its
    subscription receives them (so nothing published afterwards is missed)."""
    ns = transport.namespace
    inbox = Inbox(session, DropCounter())
    inbox.subscribe(
        "health", contract.topic("health/<service>/<w>").key(ns, service="record", w="0"), Health
    )
    probe = Publisher(session, f"hamnet/{ns}/test/probe", "test/0")
    deadline = time.monotonic() + 30
    while True:
        assert recorder.poll() is None, recorder.stdout.read()
        assert time.monotonic() < deadline, "the recorder never received anything"
        probe.put_encoded(b"probe")
        received = inbox.get(timeout=0.2)
        if received is not None and received.value.received.get("record0", 0) > 0:
            break
    inbox.close()
    probe.close()


def stop(process, sig: int = signal.SIGTERM) -> int:
    os.killpg(process.pid, sig)
    return process.wait(timeout=20)


def test_a_recorded_sim_run_replays_byte_for_byte_in_another_namespace(
    spawn, transport: TransportConfig, tmp_path: Path
) -> None:
    ns, path = transport.namespace, tmp_path / "run.mcap"
    session = open_session(transport)
    try:
        live = Capture(session, f"hamnet/{ns}/**")
        recorder = spawn("record", "-o", str(path), "--chunk-s", "0.2", *transport_args(transport))
        wait_until_recording(session, transport, recorder)
        sim = spawn("sim", "--num-envs", "2", "--num-objects", "2", "--nthread", "1",
                    "--realtime", "--max-steps", str(STEPS), *transport_args(transport))  # fmt: skip
        assert sim.wait(timeout=90) == 0, sim.stdout.read()
        raw = Publisher(session, f"hamnet/{ns}/test/raw", "test/0")
        for i in range(5):  # a key outside the contract: recorded raw, replayed all the same
            raw.put_encoded(b"\x00\xffraw %d" % i)
        time.sleep(0.5)
        assert stop(recorder) == 0, recorder.stdout.read()

        recorded = list(read_file(path))
        by_key: dict[str, list[bytes]] = defaultdict(list)
        for message in recorded:
            by_key[message.key].append(message.payload)
        # The recording is what a subscriber saw live, key by key (its own health aside).
        # What a process publishes as its session opens (the sim's first health report)
        # reaches a peer only once connected to it, so those keys may lack a first message.
        seen = live.per_key(exclude="/health/record/")
        assert set(by_key) == set(seen)
        for key, payloads in by_key.items():
            if "/health/" in key or key.endswith("/probe"):
                assert payloads == seen[key][-len(payloads) :], key
            else:
                assert payloads == seen[key], key
        states = [RobotState.FromString(p) for p in by_key[f"hamnet/{ns}/sim/0/state"]]
        steps = [s.header.step for s in states]
        assert steps == sorted(steps) and set(range(STEPS)) <= set(steps)
        state_messages = [m for m in recorded if m.key.endswith("/sim/0/state")]
        assert [m.publish_time_ns for m in state_messages] == [s.header.stamp_ns for s in states]
        schemas = {m.key: m.schema for m in recorded}
        assert (
            schemas[f"hamnet/{ns}/test/raw"] == ""
            and schemas[f"hamnet/{ns}/sim/0/scene"] == "hamnet.Scene"
        )

        into = f"{ns}r"
        replayed = Capture(session, f"hamnet/{into}/**")
        replay = spawn("replay", str(path), "--speed", "4", "--start-delay-s", "1.5",
                       "--namespace", into, "--rendezvous", transport.rendezvous)  # fmt: skip
        assert replay.wait(timeout=60) == 0, replay.stdout.read()
        deadline = time.monotonic() + 5
        while replayed.count("/health/replay/") < len(recorded) and time.monotonic() < deadline:
            time.sleep(0.1)
        moved = {key.replace(f"hamnet/{ns}/", f"hamnet/{into}/", 1): p for key, p in by_key.items()}
        assert replayed.per_key(exclude="/health/replay/") == moved
    finally:
        session.close()


def test_stepped_replay_publishes_one_step_per_stdin_line(
    transport: TransportConfig, tmp_path: Path
) -> None:
    path = tmp_path / "steps.mcap"
    messages = lock_step(6)  # steps of 4 (state 0 twice), then 3 messages each
    write(path, messages)
    session = open_session(transport)
    captured = Capture(session, f"hamnet/{transport.namespace}/**")
    process = subprocess.Popen(
        [sys.executable, "-m", "hamnet", "replay", str(path), "--step", "--start-delay-s", "1",
         *transport_args(transport)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    exclude = "/health/replay/"

    def advance(line: str, total: int) -> None:
        process.stdin.write(line)
        process.stdin.flush()
        deadline = time.monotonic() + 15
        while captured.count(exclude) < total:
            assert process.poll() is None and time.monotonic() < deadline, captured.count(exclude)
            time.sleep(0.05)
        time.sleep(0.5)  # and nothing more until asked
        assert captured.count(exclude) == total

    try:
        advance("\n", 4)
        advance("2\n", 10)
        advance("\n", 13)
        process.stdin.write("q\n")
        process.stdin.flush()
        assert process.wait(timeout=20) == 0
        output = process.stdout.read()
        assert "step 0: 4 messages" in output and "step 3: 3 messages" in output
        replayed = [(key, p) for key, p in captured.samples if exclude not in key]
        recorded = [(key.replace("hamnet/rec/", f"hamnet/{transport.namespace}/"), p)
                    for key, p, _ in messages[:13]]  # fmt: skip
        assert sorted(replayed) == sorted(recorded)
        for key in {k for k, _ in recorded}:
            assert [p for k, p in replayed if k == key] == [p for k, p in recorded if k == key]
    finally:
        if process.poll() is None:
            stop(process, signal.SIGKILL)
        session.close()


def test_a_recorder_killed_with_sigkill_leaves_a_file_readable_to_its_last_chunk(
    spawn, transport: TransportConfig, tmp_path: Path
) -> None:
    ns, path = transport.namespace, tmp_path / "killed.mcap"
    key = contract.topic("sim/<w>/state").key(ns, w="0")
    session = open_session(transport)
    try:
        recorder = spawn("record", "-o", str(path), "--chunk-s", "0.2", *transport_args(transport))
        wait_until_recording(session, transport, recorder)
        states = Publisher(session, key, "sim/0")
        published = []
        for step in range(60):
            message = RobotState()
            message.header.step = step
            message.q.CopyFrom(to_tensor(np.full((2, 7), step, np.float32)))
            states.put(message)
            published.append(message.SerializeToString())
            time.sleep(0.02)
        time.sleep(0.8)  # the recorder closes the chunk by age: these 60 are on disk
        for step in range(60, 70):  # most likely still in the open chunk when killed
            message = RobotState()
            message.header.step = step
            states.put(message)
            published.append(message.SerializeToString())
        assert stop(recorder, signal.SIGKILL) == -signal.SIGKILL
    finally:
        session.close()

    with open(path, "rb") as stream:
        read = []
        try:
            reader = NonSeekingReader(stream)
            for _, channel, message in reader.iter_messages(log_time_order=False):
                if channel.topic == key:
                    read.append(message.data)
        except (McapError, struct.error):
            pass  # the end of what was written: no summary, no footer
    assert len(read) >= 60 and read == published[: len(read)]
    with open(path, "rb") as stream, pytest.raises((McapError, struct.error)):
        make_reader(stream).get_summary()  # never finished: the indexed reader has no footer

    result = subprocess.run([sys.executable, "-m", "hamnet", "record", "info", str(path), "--json"],
                            capture_output=True, text=True, timeout=60)  # fmt: skip
    info = json.loads(result.stdout)
    assert not info["complete"]
    assert {t["key"]: t["messages"] for t in info["topics"]}[key] == len(read)


def overflow_of(report: Health) -> dict[str, int]:
    """Payloads the recorder's queue refused, per key, in one Health report."""
    return {d.key: d.count for d in report.drops if d.reason == "overflow"}


def test_a_burst_beyond_the_queue_is_recorded_or_counted_as_overflow_in_health(
    spawn, transport: TransportConfig, tmp_path: Path
) -> None:
    """The recorder never blocks Zenoh: with a queue of 1 payload and a writer that cannot
    write, a burst overflows the queue; every payload delivered is either in the file or
    counted as overflow in Health.

    The test holds the writer: the output is a FIFO that it reads only after the burst, so the
    recorder's first full chunk (1 MB) blocks in `write` and the burst can only overflow. The
    burst's publisher blocks rather than drops under congestion: once on a loaded machine
    Zenoh dropped a whole burst of a dropping publisher, and nothing reached the queue."""
    ns, fifo = transport.namespace, tmp_path / "burst.mcap"
    key = f"hamnet/{ns}/test/burst"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # the recorder's open does not wait
    os.set_blocking(reader, True)
    drained = bytearray()
    reports: list[Health] = []
    session = open_session(transport)
    try:
        recorder = spawn("record", "-o", str(fifo), "--queue-size", "1",
                         *transport_args(transport))  # fmt: skip
        wait_until_recording(session, transport, recorder)
        health = Inbox(session, DropCounter())
        health.subscribe(
            "health",
            contract.topic("health/<service>/<w>").key(ns, service="record", w="0"),
            Health,
        )
        burst = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
        payload = np.random.default_rng(0).bytes(200_000)
        for index in range(BURST):
            burst.put(index.to_bytes(4, "little") + payload)
        time.sleep(1.0)
        drain = threading.Thread(target=lambda: [drained.extend(part) for part in iter(
            lambda: os.read(reader, 1 << 20), b"")])  # fmt: skip
        drain.start()
        assert stop(recorder) == 0
        drain.join(timeout=30)
        while (received := health.get(timeout=1.0)) is not None:
            reports.append(received.value)
    finally:
        session.close()
        os.close(reader)
    path = tmp_path / "drained.mcap"
    path.write_bytes(drained)
    recorded = list(read_file(path))
    final = reports[-1]
    overflow = overflow_of(final)
    assert overflow.get(key, 0) > 0, (final.received, overflow, len(recorded))
    # What Zenoh delivered (the probes and the burst) was either written or counted: nothing
    # is lost silently between the callback and the file.
    assert len(recorded) + sum(overflow.values()) == final.received["record0"] >= BURST
    numbers = [int.from_bytes(m.payload[:4], "little") for m in recorded if m.key == key]
    assert numbers == sorted(numbers) and numbers  # what was kept is in order


def test_a_service_joining_a_replay_halfway_gets_the_latest_scenes_by_asking(
    transport: TransportConfig, tmp_path: Path
) -> None:
    """Scenes are replayed at the start only (as a free-running sim publishes them); a
    subscriber that joins later asks for them and gets, from the replay, the recorded
    payloads still current for some environment: byte for byte, superseded ones left out."""
    first, second, third = scene(0, [0, 1]), scene(1, [1]), scene(2, [1])
    scene_key = f"hamnet/{NS}/sim/0/scene"
    messages = [
        (scene_key, first, T0),
        (scene_key, second, T0 + 1000),
        (scene_key, third, T0 + 2000),
    ]
    messages += [
        (STATE, state(k, T0 + k * 100_000_000), T0 + k * 100_000_000 + 5000) for k in range(60)
    ]
    path = tmp_path / "scenes.mcap"
    write(path, messages)
    process = subprocess.Popen(
        [sys.executable, "-m", "hamnet", "replay", str(path), "--start-delay-s", "0.5",
         *transport_args(transport)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
    )  # fmt: skip
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    ns = transport.namespace
    inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
    replayed_key = contract.topic("sim/<w>/scene").key(ns, w="0")
    inbox.subscribe("scene", replayed_key, decoder=lambda key, payload: payload)
    answers: list[bytes] = []
    try:
        deadline = time.monotonic() + 20
        states = 0
        while states < 5:  # the scenes went by before we listened to them
            assert process.poll() is None and time.monotonic() < deadline, process.stdout.read()
            received = inbox.get(timeout=0.5)
            states += received is not None and received.name == "state"
        inbox.catch_up("scene", replayed_key)
        settled = deadline
        while time.monotonic() < settled:  # the answers, then 1 s more to see nothing else
            received = inbox.get(timeout=0.1)
            if received is not None and received.name == "scene":
                answers.append(received.value)
                settled = time.monotonic() + 1.0
    finally:
        stop(process, signal.SIGKILL)
        session.close()
    assert answers == [first, third]
