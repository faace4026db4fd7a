"""`hamnet camera` as a process on real Zenoh: the sim source renders the rig's four views
(MuJoCo over EGL) at the arm pose of the states it hears; replay republishes recorded
frames; realsense without pyrealsense2 is one line and exit 2."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from hamnet.camera.frames import decode_frames, encode_frames
from hamnet.camera.views import OBJECT, SCENE
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import Publisher
from hamnet.runtime.tensor import to_tensor
from hamnet.runtime.transport import open_session
from tests.camera.frames import FRAMES, first_frames, listen, views
from tests.conftest import transport_args
from tests.recorder.recordings import T0, write


def robot_state(step: int, q: np.ndarray) -> RobotState:
    message = RobotState()
    message.header.step = step
    to_tensor(np.asarray(q, np.float32)[None], message.q)
    to_tensor(np.zeros(1, np.int64), message.episode_ids)
    return message


def test_sim_source_renders_the_rig_at_the_states_arm_pose(spawn, transport) -> None:
    camera = spawn("camera", "--source", "sim", *transport_args(transport))
    session = open_session(transport)
    try:
        inbox = listen(session, transport.namespace)
        states = Publisher(
            session, contract.topic("sim/<w>/state").key(transport.namespace, w="0"), "sim/0"
        )
        q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])
        frames = first_frames(inbox, [camera], 60, tick=lambda: states.put(robot_state(5, q)))
    finally:
        session.close()
    assert frames.header.step == 5 and [c.name for c in frames.cameras] == [
        f"d435_{i}" for i in range(4)
    ]
    got = decode_frames(frames)
    for view in got:
        assert view.depth.shape == view.labels.shape == (120, 212)
        assert (view.depth > 0).mean() > 0.9
        assert (view.labels == SCENE).any()
    assert sum(int((v.labels == OBJECT).sum()) for v in got) > 50  # the object is in view


def test_replay_republishes_recorded_frames(spawn, transport, tmp_path) -> None:
    recorded = [encode_frames(views(2), step, ["a", "b"]) for step in range(3)]
    key = FRAMES.key("rec", w="3")
    write(
        tmp_path / "frames.mcap",
        [(key, m.SerializeToString(), T0 + i * 10_000_000) for i, m in enumerate(recorded)],
    )
    session = open_session(transport)
    try:
        inbox = listen(session, transport.namespace)
        replay = spawn("camera", "--source", "replay", "--replay.files", str(tmp_path / "frames.mcap"),
                       "--replay.speed", "0.05", *transport_args(transport))  # fmt: skip
        first = first_frames(inbox, [], 30)  # the replay may start before we listen: a late step
        steps = [first.header.step]
        while len(steps) < 3 - first.header.step:
            received = inbox.get(timeout=10)
            assert received is not None, steps
            steps.append(received.value.header.step)
        assert replay.wait(timeout=20) == 0
    finally:
        session.close()
    assert steps == list(range(first.header.step, 3))
    got = decode_frames(received.value if len(steps) > 1 else first)
    np.testing.assert_array_equal(got[1].depth, views(2)[1].depth)


def test_realsense_without_pyrealsense2_is_one_line_and_exit_2() -> None:
    result = subprocess.run([sys.executable, "-m", "hamnet", "camera", "--source", "realsense"],
                            check=False, capture_output=True, text=True, timeout=60)  # fmt: skip
    assert result.returncode == 2
    assert result.stderr.strip().count("\n") == 0 and "pyrealsense2" in result.stderr, result.stderr
