"""`hamnet sim` as a process on real Zenoh: this test stands in for the safety filter,
answers each state with a command holding the arm, and checks the sim's scenes, states and
transitions, its lock-step, its episode ids, and that a malformed command is counted as a
drop while it keeps running. Also its one-shot tools (`--print-model-path`,
`--show-scene`)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import rerun

from hamnet.messages.safe_command import hold_command
from hamnet.proto.health_pb2 import Health
from hamnet.proto.sim_pb2 import RobotState, Scene, Transition
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import from_tensor
from hamnet.runtime.transport import TransportConfig, open_session
from tests.conftest import transport_args
from tests.sim.test_shell import safe_command

B, S, J = 2, 8, 7
TIMEOUT = 4
"""Episode length (policy steps) given to the sim, so that resets happen within the test."""


def test_sim_steps_in_lock_step_with_its_commands_and_drops_malformed_ones(
    spawn, transport: TransportConfig
) -> None:
    process = spawn(
        "sim", "--num-envs", str(B), "--num-objects", "2", "--nthread", "1",
        "--task.timeout", str(TIMEOUT), "--resend-s", "0.2", *transport_args(transport),
    )  # fmt: skip
    ns = transport.namespace
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    for name, topic, message in (("state", "sim/<w>/state", RobotState),
                                 ("scene", "sim/<w>/scene", Scene),
                                 ("transition", "sim/<w>/transition", Transition)):  # fmt: skip
        inbox.subscribe(name, contract.topic(topic).key(ns, w="0"), message)
    health = contract.topic("health/<service>/<w>").key(ns, service="sim", w="0")
    inbox.subscribe("health", health, Health)
    command_key = contract.topic("safety/<w>/command").key(ns, w="0")
    commands = Publisher(session, command_key, "safety/0")
    states: dict[int, RobotState] = {}
    scenes: list[Scene] = []
    transitions: list[Transition] = []
    drops: dict[tuple[str, str], int] = {}
    malformed_sent = False
    deadline = time.monotonic() + 30
    try:
        while len(transitions) < 2 * TIMEOUT + 1 or not drops:
            assert process.poll() is None, process.stdout.read()
            assert time.monotonic() < deadline, f"steps {sorted(states)}, drops {drops}"
            received = inbox.get(timeout=0.5)
            if received is None:
                continue
            if received.name == "health":
                drops = {(d.key, d.reason): d.count for d in received.value.drops}
                continue
            if received.name == "scene":
                scenes.append(received.value)
                continue
            if received.name == "transition":
                transitions.append(received.value)
                continue
            state = received.value
            step = state.header.step
            last = max(states, default=0)
            assert step in (last, last + 1), f"state {step} after state {last}: not lock-step"
            states[step] = state
            q = from_tensor(state.q, np.float32, (B, J))
            command = hold_command(q, S)
            if step == 3 and not malformed_sent:  # one env too few: must be dropped, not run
                short = {n: getattr(command, n)[:1] for n in ("q_ref", "kp", "kd", "tau_limit")}
                commands.put(safe_command(command, step, **short))
                malformed_sent = True
            # Answered again on each resent state 0: the first puts may precede the route.
            commands.put(safe_command(command, step))
    finally:
        session.close()
    assert process.poll() is None, "the sim died"
    assert drops == {(command_key, "shape"): 1}

    # Lock-step: one transition per command, numbered like the state it answered.
    assert [t.header.step for t in transitions] == list(range(len(transitions)))
    for t in transitions:
        assert from_tensor(t.reward_terms, np.float32, (B, 3)).shape == (B, 3)
        assert list(t.reward_names) == ["success", "goal", "contact"]
        for flag in ("terminated", "truncated", "success"):
            from_tensor(getattr(t, flag), bool, (B,))
        state = states[t.header.step]  # transition k belongs to the episodes of state k
        np.testing.assert_array_equal(from_tensor(t.episode_ids), from_tensor(state.episode_ids))
    truncated = np.array([from_tensor(t.truncated, bool) for t in transitions])  # (T, B)
    assert truncated[TIMEOUT - 1].all() and truncated[2 * TIMEOUT - 1].all()

    # Scenes: every environment at the start (sent again while nobody answered), then the
    # reset environments, with the episode ids of the state they start in.
    first = [s for s in scenes if s.header.step == 0]
    assert first and all(from_tensor(s.env_ids).tolist() == [0, 1] for s in first)
    # A scene sent just before the test stopped listening may have no state here yet.
    later = [s for s in scenes if 0 < s.header.step <= max(states)]
    assert [s.header.step for s in later][:2] == [TIMEOUT, 2 * TIMEOUT]
    for scene in later:
        new = from_tensor(scene.episode_ids, np.int64, (B,))
        np.testing.assert_array_equal(new, from_tensor(states[scene.header.step].episode_ids))
        assert len(scene.object_ids) == B and all("@" in name for name in scene.object_ids)
        assert from_tensor(scene.cuboid_pos, np.float32).shape == (B, 16, 3)
        assert from_tensor(scene.env_code, np.float32).shape == (B, 25)
    ids = [from_tensor(states[k].episode_ids).tolist() for k in (0, TIMEOUT, 2 * TIMEOUT)]
    assert ids == [[0, 1], [2, 3], [4, 5]]


def test_a_service_started_late_gets_every_scene_by_asking(spawn, transport) -> None:
    """A free-running sim publishes scenes only at resets: a subscriber that starts after
    them would wait a whole episode. Its query is answered with the scenes of every
    environment, stamped with the current step (so not a resend of the first ones)."""
    process = spawn(
        "sim", "--num-envs", str(B), "--num-objects", "2", "--nthread", "1", "--realtime",
        "--task.timeout", "1000", *transport_args(transport),
    )  # fmt: skip
    ns = transport.namespace
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
    scene_key = contract.topic("sim/<w>/scene").key(ns, w="0")
    inbox.subscribe("scene", scene_key, Scene)
    deadline = time.monotonic() + 30
    latest, scene, asked = None, None, False
    try:
        while scene is None:
            assert process.poll() is None, process.stdout.read()
            assert time.monotonic() < deadline, f"no scene answer; latest state {latest}"
            received = inbox.get(timeout=0.5)
            if received is None:
                continue
            if received.name == "state":
                latest = received.value
                if latest.header.step >= 3 and not asked:
                    inbox.catch_up("scene", scene_key)
                    asked = True
            elif asked and received.value.header.step >= 3:
                scene = received.value
    finally:
        session.close()
    assert from_tensor(scene.env_ids).tolist() == list(range(B))
    np.testing.assert_array_equal(from_tensor(scene.episode_ids), from_tensor(latest.episode_ids))
    assert scene.header.source == "sim/0" and len(scene.object_ids) == B
    assert from_tensor(scene.object_points, np.float32).shape == (B, 512, 3)


def run_sim(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "hamnet", "sim", *args], capture_output=True, text=True, timeout=60
    )


def test_print_model_path_prints_the_fr3_model_file() -> None:
    result = run_sim("--print-model-path")
    assert result.returncode == 0, result.stderr
    path = Path(result.stdout.strip())
    assert path.is_file() and path.suffix == ".xml"


def test_show_scene_writes_a_readable_recording(tmp_path: Path) -> None:
    target = tmp_path / "scenes" / "three.rrd"
    result = run_sim("--show-scene", "3", "--scene-file", str(target))
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == str(target)
    chunks = rerun.chunk.RrdReader(target).stream().to_chunks()
    assert {"/scene/base", "/scene/start", "/scene/goal"} <= {c.entity_path for c in chunks}
