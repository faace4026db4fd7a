"""DepthFrames on the wire: encode the views of one frame time, decode and check them.

Pure functions shared by the camera service (which encodes) and perception (which decodes),
so both ends agree on shapes and dtypes: depth (H, W) float32 m, intrinsics (3, 3) and
camera-to-world (4, 4) float64, optional labels (H, W) uint8.
"""

from __future__ import annotations

import numpy as np

from hamnet.camera.views import DepthView
from hamnet.proto.camera_pb2 import DepthFrames
from hamnet.proto.common_pb2 import Header
from hamnet.runtime.tensor import PayloadError, field_array, to_tensor


def encode_frames(views: list[DepthView], step: int, names: list[str] | None = None) -> DepthFrames:
    """One DepthFrames message of `views` (names default to `camera_<i>`)."""
    names = names if names is not None else [f"camera_{i}" for i in range(len(views))]
    if len(names) != len(views):
        raise ValueError(f"{len(names)} names for {len(views)} views")
    message = DepthFrames(header=Header(step=step))
    for name, view in zip(names, views):
        frame = message.cameras.add(name=name)
        to_tensor(np.ascontiguousarray(view.depth, np.float32), frame.depth)
        to_tensor(np.asarray(view.intrinsics, np.float64), frame.intrinsics)
        to_tensor(np.asarray(view.camera_to_world, np.float64), frame.camera_to_world)
        if view.labels is not None:
            to_tensor(np.ascontiguousarray(view.labels, np.uint8), frame.labels)
    return message


def decode_frames(message: DepthFrames) -> list[DepthView]:
    """The views of a DepthFrames message (read-only arrays over the payload).

    Raises:
        PayloadError: `missing` (no camera, or a required field unset), `dtype`, `shape`
            (labels not the depth's size, a matrix not 3x3 / 4x4), `nonfinite`, `range`
            (negative depth, a pose that is not a rigid transform).
    """
    if not message.cameras:
        raise PayloadError("missing", "DepthFrames holds no camera")
    views = []
    for frame in message.cameras:
        depth = field_array(frame, "depth", np.float32, (None, None), finite=True)
        if (depth < 0).any():
            raise PayloadError("range", f"camera {frame.name!r}: negative depth")
        k = field_array(frame, "intrinsics", np.float64, (3, 3), finite=True)
        pose = field_array(frame, "camera_to_world", np.float64, (4, 4), finite=True)
        rotation = pose[:3, :3]
        if not (
            np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-4)
            and np.allclose(pose[3], [0, 0, 0, 1])
        ):
            raise PayloadError(
                "range", f"camera {frame.name!r}: camera_to_world is not a rigid transform"
            )
        labels = None
        if frame.HasField("labels"):
            labels = field_array(frame, "labels", np.uint8, depth.shape)
        views.append(DepthView(depth, labels, k, pose))
    return views
