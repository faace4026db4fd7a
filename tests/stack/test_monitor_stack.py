"""`hamnet monitor --save` beside a real free-running `hamnet sim`, both as processes on
real Zenoh. The monitor starts after the sim has published its scenes (a free-running sim
publishes them only at resets), so it has to ask the sim for them. After a few seconds the
monitor is stopped (SIGTERM, as `hamnet up` stops it)
and its .rrd file holds the FR3, posed at each drawn step where the sim's own state puts
its end effector, the focus environment's scene cuboids, object and goal, and the reward
terms; its Health reports what it received and that it dropped (almost) nothing at 10 Hz."""

from __future__ import annotations

import os
import signal
import time

import numpy as np

from hamnet.proto.health_pb2 import Health
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox
from hamnet.runtime.tensor import from_tensor
from hamnet.runtime.transport import TransportConfig, open_session
from tests.conftest import transport_args
from tests.monitor.recorded import Rrd, drawn_ee

B, ENV = 2, 1


def test_monitor_saves_the_robot_and_scene_of_a_running_sim(
    spawn, transport: TransportConfig, tmp_path
) -> None:
    path = tmp_path / "monitor.rrd"
    ns = transport.namespace
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    try:
        health_key = contract.topic("health/<service>/<w>").key(ns, service="monitor", w="0")
        inbox.subscribe("health", health_key, Health)
        sim = spawn("sim", "--num-envs", str(B), "--num-objects", "2", "--nthread", "1", "--realtime",
                    *transport_args(transport))  # fmt: skip
        inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
        states: dict[int, RobotState] = {}
        deadline = time.monotonic() + 30
        while len(states) < 3:  # the sim runs: its first scenes are gone
            assert sim.poll() is None, sim.stdout.read()
            assert time.monotonic() < deadline, "the sim did not start"
            received = inbox.get(timeout=0.5)
            if received is not None and received.name == "state":
                states[received.value.header.step] = received.value
        monitor = spawn(
            "monitor", "--save", str(path), "--env", str(ENV), *transport_args(transport)
        )
        health = Health()
        while health.received.get("state", 0) < 20:
            assert monitor.poll() is None, monitor.stdout.read()
            assert sim.poll() is None, sim.stdout.read()
            assert time.monotonic() < deadline, f"monitor health: {health}"
            received = inbox.get(timeout=0.5)
            if received is None:
                continue
            if received.name == "state":
                states[received.value.header.step] = received.value
            else:
                health = received.value
    finally:
        session.close()
    # At 10 Hz under the 30 Hz cap nothing is dropped, but for a state or two that a busy
    # machine delivers within 1/30 s of the previous one while the monitor starts up.
    assert all(d.reason == "rate" for d in health.drops), health.drops
    assert sum(d.count for d in health.drops) <= 2, health.drops
    os.killpg(monitor.pid, signal.SIGTERM)
    assert monitor.wait(timeout=10) == 0, monitor.stdout.read()

    rrd = Rrd(path)
    assert {"/robot/fr3_link0/boxes", "/robot/fr3_paddle/boxes", "/scene/base", "/scene/goal",
            "/object/surface", "/goal", "/rewards/goal"} <= rrd.entities  # fmt: skip
    assert rrd.rows("/scene/base", "Boxes3D:half_sizes"), "no scene cuboids"
    drawn = rrd.rows("/robot/fr3_paddle", "Transform3D:translation")
    compared = sorted(set(drawn) & set(states))
    assert len(compared) >= 10, (sorted(drawn), sorted(states))
    for step in compared:
        ee = from_tensor(states[step].ee_pos_rot6d, np.float32, (B, 9))[ENV, :3]
        np.testing.assert_allclose(drawn_ee(rrd, step), ee, atol=1e-4)
