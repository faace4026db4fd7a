"""`hamnet sim` and `hamnet perception` as processes on real Zenoh: on the wire, the
environment clouds of the perception tokens see only what a camera above the table sees.
This test stands in for the safety filter (it answers each state with a command holding the
arm), pairs every environment's cloud with the scene the sim published for that episode and
counts the points that lie under the table top minus 1 cm or off the table's footprint.
Before the crop, 42% of the points lay under the top and 19% off the footprint."""

from __future__ import annotations

import time

import numpy as np

from hamnet.messages.safe_command import hold_command
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.sim_pb2 import RobotState, Scene
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import from_tensor
from hamnet.runtime.transport import TransportConfig, open_session
from hamnet.sim.quaternion import to_matrix
from hamnet.task.cuboids import TABLE
from tests.conftest import transport_args
from tests.sim.test_shell import safe_command

B, S, J, P = 8, 8, 7, 512
TIMEOUT = 2
"""Episode length (policy steps): a new scene per environment every two steps."""
SCENES = 32
"""(environment, episode) pairs to measure."""
MARGIN = 1e-4
"""Tolerance of the footprint test, m: points on a wall's inner face lie on the table's edge
(float32 on the wire)."""


def table_frames(scene: Scene) -> dict[tuple[int, int], tuple[np.ndarray, ...]]:
    """(env, episode) -> the table's centre (3,), rotation (3, 3) and half extent (3,)."""
    k = len(scene.object_ids)
    table = lambda name, width: from_tensor(  # noqa: E731
        getattr(scene, name), np.float32, (k, None, width)
    )[:, TABLE].astype(np.float64)  # (K, width)
    centre, quat = table("cuboid_pos", 3), table("cuboid_quat", 4)
    half = table("cuboid_half_size", 3)
    envs, episodes = from_tensor(scene.env_ids), from_tensor(scene.episode_ids)
    rotation = to_matrix(quat / np.linalg.norm(quat, axis=-1, keepdims=True))  # (K, 3, 3)
    return {
        (int(e), int(ep)): (centre[i], rotation[i], half[i])
        for i, (e, ep) in enumerate(zip(envs, episodes, strict=True))
    }


def outside_share(cloud: np.ndarray, centre: np.ndarray, rotation: np.ndarray, half: np.ndarray):
    """Share of the points (P, 3) under the table top minus 1 cm or off its footprint."""
    local = (cloud.astype(np.float64) - centre) @ rotation  # (P, 3), table frame
    below = local[:, 2] < half[2] - 0.01 - MARGIN
    off = (np.abs(local[:, :2]) > half[:2] + MARGIN).any(-1)
    return float((below | off).mean()), float(below.mean()), float(off.mean())


def test_environment_clouds_on_the_wire_lie_over_the_table(
    spawn, transport: TransportConfig
) -> None:
    sim = spawn(
        "sim", "--num-envs", str(B), "--num-objects", "2", "--nthread", "1",
        "--task.timeout", str(TIMEOUT), "--resend-s", "0.2", *transport_args(transport),
    )  # fmt: skip
    perception = spawn("perception", "--random-init", *transport_args(transport))
    ns = transport.namespace
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("state", contract.topic("sim/<w>/state").key(ns, w="0"), RobotState)
    inbox.subscribe("scene", contract.topic("sim/<w>/scene").key(ns, w="0"), Scene)
    tokens_key = contract.topic("perception/<w>/tokens").key(ns, w="0")
    inbox.subscribe("tokens", tokens_key, PerceptionTokens)
    commands = Publisher(session, contract.topic("safety/<w>/command").key(ns, w="0"), "safety/0")
    tables: dict[tuple[int, int], tuple] = {}
    clouds: dict[tuple[int, int], np.ndarray] = {}
    deadline = time.monotonic() + 120
    try:
        while len(clouds.keys() & tables.keys()) < SCENES:
            for process in (sim, perception):
                assert process.poll() is None, process.stdout.read()
            assert time.monotonic() < deadline, f"{len(clouds)} clouds, {len(tables)} scenes"
            received = inbox.get(timeout=0.5)
            if received is None:
                continue
            if received.name == "scene":
                tables.update(table_frames(received.value))
            elif received.name == "tokens":
                tokens = received.value
                cloud = from_tensor(tokens.environment_cloud, np.float32, (B, P, 3))
                for env, episode in enumerate(from_tensor(tokens.episode_ids).tolist()):
                    clouds[(env, int(episode))] = cloud[env]
            else:
                # Answered again on each resent state: the first puts may precede the route.
                state = received.value
                q = from_tensor(state.q, np.float32, (B, J))
                commands.put(safe_command(hold_command(q, S), state.header.step))
    finally:
        session.close()

    pairs = sorted(clouds.keys() & tables.keys())
    shares = np.array([outside_share(clouds[pair], *tables[pair]) for pair in pairs])  # (N, 3)
    outside, below, off = shares.mean(0)
    print(f"{len(pairs)} scenes: {outside:.3%} outside ({below:.3%} below, {off:.3%} off)")
    assert len(pairs) >= SCENES
    assert outside < 0.01, f"{outside:.2%} outside ({below:.2%} below, {off:.2%} off the footprint)"
    # The clouds are the scenes' (not, say, all on one plane): nearly all points at or above
    # the top (the 1 cm band of the table's sides is small), many on it, some on plates and
    # walls above it.
    heights = np.concatenate([
        (clouds[p].astype(np.float64) - tables[p][0]) @ tables[p][1][:, 2] - tables[p][2][2]
        for p in pairs
    ])  # fmt: skip
    assert np.mean(heights > -1e-3) > 0.95
    assert np.mean(np.abs(heights) < 1e-3) > 0.1 and np.mean(heights > 0.02) > 0.1
