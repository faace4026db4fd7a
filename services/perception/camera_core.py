"""Clouds and tokens from depth frames (`hamnet perception --clouds-from cameras`): the real
robot's path to the same `Percepts` the sim path (`core.Perception`) makes from the sim's
scene message and privileged object pose.

From one frame time's views of one robot (B = 1): the segmenter splits the fused points
into object and scene (`segmenters`); the scene points, resampled to the scene pool S, give
the environment cloud (its first P points, as `core.Perception`) and the local cloud (the P
pool points nearest 64 FPS keypoints of the object cloud, `cloud_ops.local_cloud`); the object
cloud is resampled to P. Everything is re-encoded each frame: the cameras see the scene
change as the arm moves and the object as it is pushed.

The object's frame: the sim path encodes the object cloud in the object's frame; here the
frame is the pose estimated from the object cloud itself (`object_pose.estimate_pose`: the
centroid and a yaw from the cloud's principal axis; the paper tracks the pose with
FoundationPose), which also goes to the robot's state through the bridge. No noise or
dropout is added: the cameras bring their own.
"""

from __future__ import annotations

import numpy as np
import torch

from hamnet.camera.views import DepthView
from hamnet.perception.cameras import resample
from hamnet.perception.cloud_ops import farthest_point_sample, gather, local_cloud
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import Percepts, encode, encoder_for
from hamnet.perception.object_pose import estimate_pose
from hamnet.perception.segmenters import Segmenter
from hamnet.perception.unicorn import UniCORN
from hamnet.runtime.compute import use_bfloat16
from hamnet.sim.quaternion import to_matrix


class NothingSeen(ValueError):
    """The frames show no object (or no scene): no clouds can be made from them."""


class CameraPerception:
    """Clouds and UniCORN tokens of one robot from its cameras' depth frames."""

    def __init__(
        self,
        encoder: UniCORN,
        segmenter: Segmenter,
        config: CloudConfig | None = None,
        device: str | torch.device = "cpu",
        seed: int = 0,
    ) -> None:
        self.config = config = config if config is not None else CloudConfig()
        self.device = torch.device(device)
        self.encoder = encoder_for(encoder, config, self.device)
        self.bfloat16 = use_bfloat16(config.encoder_precision, self.device)
        self.segmenter = segmenter
        self.rng = np.random.default_rng(seed)

    @torch.no_grad()
    def percepts(self, views: list[DepthView]) -> tuple[Percepts, np.ndarray]:
        """The clouds (1, P, 3), world frame, m, and tokens (1, 1 + K, D) of one frame time,
        and the object's estimated pose (7,): position (m), quaternion wxyz.

        Raises:
            NothingSeen: the segmenter found no object or no scene points.
        """
        config = self.config
        object_points, scene_points = self.segmenter.split(views)
        if len(object_points) == 0 or len(scene_points) == 0:
            raise NothingSeen(
                f"{len(object_points)} object and {len(scene_points)} scene points in the frames"
            )
        tensor = lambda a: torch.as_tensor(a, dtype=torch.float32, device=self.device)[None]
        obj = tensor(resample(object_points, config.num_points, self.rng))  # (1, P, 3)
        pool = tensor(resample(scene_points, config.scene_pool, self.rng))  # (1, S, 3)
        environment = pool[:, : config.num_points]
        keypoints = gather(obj, farthest_point_sample(obj, config.num_keypoints))  # (1, K, 3)
        local = local_cloud(pool, keypoints, config.num_points)
        pose = estimate_pose(object_points)
        rotation = tensor(to_matrix(pose[3:]))  # (1, 3, 3)
        in_object_frame = (obj - tensor(pose[None, :3])) @ rotation  # R^T (p - c), row-wise
        object_tokens, local_tokens, global_tokens = encode(
            self.encoder, torch.cat([in_object_frame, local, environment]), self.bfloat16
        ).split(1)
        percepts = Percepts(obj, environment, local, object_tokens, local_tokens, global_tokens)
        return percepts, pose
