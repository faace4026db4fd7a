"""The depth-camera path of perception: the plane segmenter on a synthetic depth image of a
box on a table (open3d ray casting), and `hamnet perception --clouds-from cameras` as a
process on real Zenoh, fed by `hamnet camera --source sim` (MuJoCo EGL renders): its object
cloud lies on the rendered object's true surface."""

from __future__ import annotations

import time

import numpy as np
import open3d as o3d
import torch

from hamnet.camera.sim_source import sim_world
from hamnet.camera.sources import SimSourceConfig
from hamnet.camera.views import DepthView
from hamnet.perception.cloud_ops import pose_points
from hamnet.perception.config import CameraConfig, PlaneConfig
from hamnet.perception.segmenters import PlaneSegmenter
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.tensor import from_tensor
from hamnet.runtime.transport import open_session
from hamnet.sim.shell import encode_state
from tests.conftest import transport_args

BOX_MIN, BOX_MAX = np.array([0.55, 0.05, 0.4]), np.array([0.65, 0.13, 0.48])
"""The box standing on the table top (z = 0.4 m)."""


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(4, 4) OpenCV camera-to-world pose of a camera at `eye` looking at `target`."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([right, np.cross(forward, right), forward], axis=1)
    pose[:3, 3] = eye
    return pose


def ray_cast_view(
    scene: o3d.t.geometry.RaycastingScene, eye: np.ndarray, w: int = 160, h: int = 120
) -> DepthView:
    k = np.array([[140.0, 0, w / 2 - 0.5], [0, 140.0, h / 2 - 0.5], [0, 0, 1]])
    pose = look_at(eye, np.array([0.6, 0.0, 0.4]))
    rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(
        o3d.core.Tensor(k), o3d.core.Tensor(np.linalg.inv(pose)), w, h
    ).numpy()  # (h, w, 6): origin, direction
    t = scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))["t_hit"].numpy()
    depth = t * (rays[..., 3:] @ pose[:3, 2])  # along the optical axis
    return DepthView(np.where(np.isfinite(depth), depth, 0.0).astype(np.float32), None, k, pose)


def test_plane_segmenter_finds_the_box_on_the_table() -> None:
    scene = o3d.t.geometry.RaycastingScene()
    table = o3d.geometry.TriangleMesh.create_box(1.0, 1.2, 0.05).translate((0.1, -0.6, 0.35))
    box = o3d.geometry.TriangleMesh.create_box(*(BOX_MAX - BOX_MIN)).translate(BOX_MIN)
    for mesh in (table, box):
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    views = [ray_cast_view(scene, np.array(eye)) for eye in ((-0.2, -0.5, 1.1), (1.3, 0.6, 1.0))]
    obj, rest = PlaneSegmenter(CameraConfig(), PlaneConfig()).split(views)
    assert len(obj) > 100 and len(rest) > 1000
    assert (obj >= BOX_MIN - 0.015).all() and (obj <= BOX_MAX + 0.015).all()
    on_box = ((rest >= BOX_MIN + 0.015) & (rest <= BOX_MAX - 0.015)).all(1)
    assert not on_box.any()  # nothing of the box stayed in the scene
    assert abs(np.median(rest[:, 2]) - 0.4) < 0.01  # the scene is the table top


def test_perception_from_rendered_frames_sees_the_true_object(spawn, transport) -> None:
    """camera (sim source) -> perception --clouds-from cameras: the tokens answer the
    state's step and episode, and their object cloud lies on the object's true surface."""
    camera = spawn("camera", "--source", "sim", *transport_args(transport))
    perception = spawn(
        "perception", "--clouds-from", "cameras", "--random-init", *transport_args(transport)
    )
    env = sim_world(SimSourceConfig())  # the camera's own world, same seed
    obs = env.observe()
    surface = pose_points(
        torch.tensor(env.scenes(np.array([0])).object_points), torch.tensor(obs.object_pose)
    )[0]
    ns = transport.namespace
    session = open_session(transport)
    try:
        inbox = Inbox(session, DropCounter())
        inbox.subscribe(
            "tokens", contract.topic("perception/<w>/tokens").key(ns, w="0"), PerceptionTokens
        )
        states = Publisher(session, contract.topic("sim/<w>/state").key(ns, w="0"), "sim/0")
        deadline, step, tokens = time.monotonic() + 90, 0, None
        while tokens is None:
            for process in (camera, perception):
                assert process.poll() is None, process.stdout.read()
            assert time.monotonic() < deadline, "no tokens"
            step += 1
            states.put(encode_state(obs, step))
            received = inbox.get(timeout=0.3)
            tokens = None if received is None else received.value
    finally:
        session.close()
    assert 1 <= tokens.header.step <= step
    assert from_tensor(tokens.episode_ids, np.int64, (1,)).tolist() == obs.episode_ids.tolist()
    for name in ("object_tokens", "local_tokens", "global_tokens"):
        from_tensor(getattr(tokens, name), np.float32, (1, 17, 128))  # finite, this shape
    cloud = torch.tensor(from_tensor(tokens.object_cloud, np.float32, (1, 512, 3))[0].copy())
    to_surface = torch.cdist(cloud, surface).min(1).values
    median, worst = float(to_surface.median()), float(to_surface.max())
    assert median < 0.01 and worst < 0.03, (median, worst)  # 6.5 mm and 2 cm when written
    local = torch.tensor(from_tensor(tokens.local_cloud, np.float32, (1, 512, 3))[0].copy())
    assert float(torch.cdist(local, cloud).min(1).values.median()) < 0.1  # around the object
