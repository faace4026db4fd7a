"""The README's first command: `hamnet up compose/demo.yaml` runs the whole loop (sim ->
perception -> policy -> safety -> sim, monitored and recorded), ends by itself, and says
which services are not built yet. Its recording then replays into a monitor and a
perception service started for it, which work on it as on the live stack."""

from __future__ import annotations

import signal
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from hamnet.cli import COMMANDS
from hamnet.launcher.stack import Stack, load
from hamnet.perception.checkpoint import SHIPPED_ENCODER, load_checkpoint
from hamnet.proto.health_pb2 import Health, ServiceState
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.recorder.headers import header_of
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox
from hamnet.runtime.recordings import read_recording
from hamnet.runtime.tensor import from_tensor
from hamnet.runtime.transport import TransportConfig, open_session
from tests.conftest import free_port, transport_args
from tests.monitor.recorded import Rrd
from tests.stack.up import alive, up

DEMO = Path(__file__).resolve().parents[2] / "compose" / "demo.yaml"
LOOP = ("sim/<w>/state", "sim/<w>/scene", "perception/<w>/tokens", "policy/<w>/action",
        "safety/<w>/command", "sim/<w>/transition")  # fmt: skip
"""The topics of one turn of the control loop, all in the recording."""


def isolated() -> TransportConfig:
    """A namespace and rendezvous of its own (the `transport` fixture, for module scope)."""
    return TransportConfig(namespace=f"test{uuid.uuid4().hex[:10]}",
                           rendezvous=f"tcp/127.0.0.1:{free_port()}")  # fmt: skip


@dataclass(frozen=True)
class DemoRun:
    stack: Stack
    transport: TransportConfig
    summary: dict
    folder: Path
    log: str
    """What `hamnet up` printed."""

    def key(self, path: str) -> str:
        return contract.topic(path).key(self.transport.namespace, w="0")

    def output(self, suffix: str) -> Path:
        namespace = self.transport.namespace
        declared = (path.replace("<namespace>", namespace) for path in self.stack.outputs)
        return self.folder / next(path for path in declared if path.endswith(suffix))


def recorded_steps(demo: DemoRun) -> dict[str, set[int]]:
    """Header steps of each loop topic in the demo's recording."""
    keys = {demo.key(path): path for path in LOOP}
    steps: dict[str, set[int]] = {path: set() for path in LOOP}
    for message in read_recording([demo.output(".mcap")]):
        if message.key in keys:
            steps[keys[message.key]].add(header_of(message.key, message.payload).step)
    return steps


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> DemoRun:
    folder, transport = tmp_path_factory.mktemp("demo"), isolated()
    # The stack's own 40 s: the trainer and its rollout worker take about 16 s to come up on
    # a busy 2-core machine (imports, the sim's first reset, the encoder), so a shorter demo
    # (it was 20 s) ends before they have trained.
    with up(DEMO, transport, cwd=folder) as run:
        assert run.wait(timeout=120) == 0, run.output
    return DemoRun(load(DEMO), transport, run.summary(), folder, run.output)


def test_demo_closes_the_loop_records_it_and_lists_the_missing_services(demo: DemoRun):
    summary, stack = demo.summary, demo.stack
    assert summary["ended"] == f"duration of {demo.stack.duration_s:g} s reached"
    commands = {c.name: c for c in COMMANDS}
    built = {name for name, spec in stack.services.items() if commands[spec.command].module}
    for name in set(stack.services) - built:
        issue = commands[stack.services[name].command].issue
        assert (f"{name} (issue #{issue})" if issue else name) in summary["not_built"]
    processes = {p["service"]: p for p in summary["processes"]}
    assert set(processes) == built
    assert all(p["announced"] >= 1 and p["restarts"] == 0 for p in processes.values()), processes
    assert not any(alive(pid) for p in processes.values() for pid in p["pids"])
    # The trainer made its updates while the loop ran, and ended by itself: a stop, which
    # the launcher does not take for a hang (its token goes seconds before its process).
    assert processes["trainer"]["outcome"] == "finished", processes["trainer"]
    assert "lost its liveliness token" not in demo.log

    # The loop turned: every service in it answered the previous one, step after step. The
    # sim's steps are its transitions. Before the policy is up, safety brakes the states
    # (how many depends on how long the services take to start on a busy machine), so the
    # recording shows what counts: from the policy's first action on, every state the sim
    # published was answered by perception, the policy and safety, bar a few the policy
    # skips while it swaps in the trainer's weights (about one announcement a second).
    steps = processes["sim"]["published"][demo.key("sim/<w>/transition")]
    assert steps >= 20, processes["sim"]
    assert processes["sim"]["received"]["command"] >= steps
    answered = recorded_steps(demo)
    first = min(answered["policy/<w>/action"])
    states = {k for k in answered["sim/<w>/state"] if k >= first}
    assert len(states) >= 10, f"the policy acted from step {first} of {max(states)}"
    for path, share in (("perception/<w>/tokens", 0.97), ("policy/<w>/action", 0.9),
                        ("safety/<w>/command", 0.97)):  # fmt: skip
        assert len(states & answered[path]) >= share * len(states), (path, sorted(states - answered[path]))
    assert not processes["policy"]["drops"] and not processes["safety"]["drops"]

    declared = {path.replace("<namespace>", demo.transport.namespace) for path in stack.outputs}
    assert set(summary["outputs"]) == declared and not summary["outputs_missing"]
    with demo.output(".mcap").open("rb") as stream:
        channels = make_reader(stream).get_summary().channels.values()
    assert {demo.key(path) for path in LOOP} <= {channel.topic for channel in channels}

    # Perception encoded with the pre-trained encoder shipped in the package, not random weights.
    tokens = demo.key("perception/<w>/tokens")
    versions = {PerceptionTokens.FromString(m.payload).encoder_version
                for m in read_recording([demo.output(".mcap")]) if m.key == tokens}  # fmt: skip
    assert versions == {load_checkpoint(SHIPPED_ENCODER)[1]} and 0 not in versions


def test_the_recording_replays_into_a_monitor_and_a_perception_service(demo: DemoRun, spawn, tmp_path):
    """Replay the demo's sim, policy and safety topics into a fresh namespace, where a
    perception service computes tokens from the replayed states and scenes (joining after
    the first scenes: it asks the replay for them) and a monitor draws it all."""
    transport = isolated()
    rrd_path = tmp_path / "replay.rrd"
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    ns = transport.namespace
    inbox.subscribe("health", contract.topic("health/<service>/<w>").pattern_in(ns), Health)
    inbox.subscribe("tokens", contract.topic("perception/<w>/tokens").key(ns, w="0"), PerceptionTokens)
    monitor = spawn("monitor", "--save", str(rrd_path), *transport_args(transport))
    # Half speed: the loop turns only in the last seconds of the demo (its services start
    # first), and perception, started once the replay runs, must be up while they replay.
    replay = spawn("replay", str(demo.output(".mcap")), "--speed", "0.5",
                   "--topics", "hamnet/*/sim/**", "hamnet/*/policy/**", "hamnet/*/safety/**",
                   *transport_args(transport))  # fmt: skip
    perception = None
    tokens: list[PerceptionTokens] = []
    running: set[str] = set()
    deadline = time.monotonic() + 90
    try:
        while replay.poll() is None or "perception" not in running:  # stopped only once it is up
            assert time.monotonic() < deadline, f"running {running}, {len(tokens)} tokens"
            received = inbox.get(timeout=0.2)
            if received is not None and received.name == "health":
                if received.value.state == ServiceState.RUNNING:
                    running.add(received.value.service)
            elif received is not None:
                tokens.append(received.value)
            if perception is None and {"monitor", "replay"} <= running:
                time.sleep(1.0)  # the replay is under way: the first scenes went by
                perception = spawn("perception", "--random-init", *transport_args(transport))
        assert replay.returncode == 0, replay.stdout.read()
    finally:
        session.close()
    for process in (monitor, perception):
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=15) == 0, process.stdout.read()

    assert len(tokens) >= 10, f"perception answered {len(tokens)} replayed states"
    cloud = from_tensor(tokens[-1].object_cloud, np.float32, (None, 512, 3))
    assert np.isfinite(cloud).all() and tokens[-1].encoder_version == 0
    rrd = Rrd(rrd_path)
    drawn = {"/robot/fr3_paddle/boxes", "/scene/base", "/object/surface", "/goal",
             "/clouds/object", "/clouds/local", "/policy/module_weights"}  # fmt: skip
    assert drawn <= rrd.entities, sorted(rrd.entities)
