"""Clouds and tokens from depth frames (`hamnet perception --clouds-from cameras`): the real
robot's path to the same `Percepts` the sim path (`core.Perception`) makes from the sim's
scene message and privileged object pose.

From one frame time's views of one robot (B = 1): the segmenter splits the fused points
into object and scene (`segmenters`); the scene points, resampled to the scene pool S, give
the environment cloud (its first P points, as `core.Perception`) and the local cloud (the P
pool points nearest 64 FPS keypoints of the object cloud, `clouds.local_cloud`); the object
cloud is resampled to P. Everything is re-encoded each frame: the cameras see the scene
change as the arm moves and the object as it is pushed.

What cameras cannot give (docs/cameras.md): the object's own frame. The sim path encodes
the object cloud in the object's frame; here it is centred on its centroid, axes of the
world, since no pose estimate exists on the real setup yet (the paper uses FoundationPose).
No noise or dropout is added: the cameras bring their own.
"""

from __future__ import annotations

import numpy as np
import torch

from hamnet.perception.cameras import DepthView, resample
from hamnet.perception.clouds import farthest_point_sample, gather, local_cloud
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import Percepts
from hamnet.perception.segmenters import Segmenter
from hamnet.perception.unicorn import UniCORN


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
        if encoder.config.num_points != config.num_points:
            raise ValueError(
                f"the encoder takes {encoder.config.num_points} points, clouds have {config.num_points}"
            )
        self.device = torch.device(device)
        self.encoder = encoder.to(self.device).eval()
        self.segmenter = segmenter
        self.rng = np.random.default_rng(seed)

    @torch.no_grad()
    def percepts(self, views: list[DepthView]) -> Percepts:
        """The clouds (1, P, 3), world frame, m, and tokens (1, 1 + K, D) of one frame time.

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
        centred = obj - obj.mean(1, keepdim=True)  # no pose estimate: the centroid's frame
        object_tokens, local_tokens, global_tokens = self.encoder(
            torch.cat([centred, local, environment])
        ).split(1)
        return Percepts(obj, environment, local, object_tokens, local_tokens, global_tokens)
