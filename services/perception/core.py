"""The perception core: per-environment caches of scene and object clouds and tokens, and
the per-step work (pose the object, gather the local cloud, encode it).

What changes when (paper: object tokens once per episode, scene tokens at reset, local
tokens every step):
- at an episode's start (`start_episodes`): the scene's visible surface, cropped to the
  workspace over the table (`scene_cloud.workspace_box`), is sampled into a dense pool (S
  points), its first P points are the global cloud, encoded once; the object's surface
  points (own frame) are encoded once, and 64 FPS keypoints are picked from them;
- every step (`step`): the object cloud and the keypoints are posed, the local cloud is the P
  pool points nearest the posed keypoints (ranked over a shortlist while it provably holds
  them, `local_cloud.LocalClouds`), and only it is encoded.

Sensor noise and dropout (`CloudConfig.noise_std`, `dropout`) corrupt each cloud where it
is made: the global and object clouds once per episode, the local cloud every step.

With `CloudConfig.visibility` "cameras" (the student) the clouds show only what the four
cameras of the rig see (`visibility.py`): the scene pool keeps its visible points (resampled
to S) at an episode's start, and every step the object cloud keeps the points visible in
its current pose, is corrupted afresh and re-encoded (in its own frame, as the teacher's).
No Zenoh, no protobuf: tensors in, tensors out, on any torch device.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from hamnet.perception.cloud_ops import (
    corrupt,
    farthest_point_sample,
    gather,
    pose_points,
    quaternion_matrix,
)
from hamnet.perception.config import CloudConfig
from hamnet.perception.local_cloud import LocalClouds
from hamnet.perception.scene_cloud import Cuboids, sample_surface, workspace_box
from hamnet.perception.unicorn import UniCORN
from hamnet.perception.visibility import (
    CameraView,
    RigVisibility,
    camera_positions,
    keep,
    outward_normals,
)
from hamnet.runtime.compute import bfloat16_autocast, use_bfloat16
from hamnet.task.cuboids import TABLE

CACHES = (
    "episode_ids",
    "scene_pool",
    "environment_cloud",
    "object_points",
    "keypoints",
    "object_tokens",
    "global_tokens",
)
"""`Perception`'s per-episode caches, (B, ...) tensors (`Perception.caches` adds the
cameras' own)."""


@dataclass(frozen=True)
class EpisodeScenes:
    """The scenes of K environments that start an episode (the Scene message)."""

    env_ids: torch.Tensor
    """(K,) long, environment indices."""
    episode_ids: torch.Tensor
    """(K,) long."""
    cuboids: Cuboids
    """K scenes of C cuboid slots."""
    object_points: torch.Tensor
    """(K, P, 3) object surface points in the object's frame, m."""

    @classmethod
    def from_arrays(
        cls,
        env_ids: np.ndarray,
        episode_ids: np.ndarray,
        centre: np.ndarray,
        quat: np.ndarray,
        half_extent: np.ndarray,
        active: np.ndarray,
        object_points: np.ndarray,
    ) -> EpisodeScenes:
        """K scenes from the arrays of a Scene message or of `VectorEnv.scenes` (CPU copies).

        Args:
            env_ids, episode_ids: (K,) integers.
            centre, quat, half_extent: (K, C, 3), (K, C, 4) wxyz, (K, C, 3) cuboids, m.
            active: (K, C) bool.
            object_points: (K, P, 3) in the object's frame, m.
        """
        tensor = lambda a, dtype: torch.tensor(np.asarray(a), dtype=dtype)  # noqa: E731
        f32 = torch.float32
        cuboids = Cuboids.from_quat(
            tensor(centre, f32),
            tensor(quat, f32),
            tensor(half_extent, f32),
            tensor(active, torch.bool),
        )
        return cls(
            tensor(env_ids, torch.long),
            tensor(episode_ids, torch.long),
            cuboids,
            tensor(object_points, f32),
        )


@dataclass(frozen=True)
class Percepts:
    """One step of every environment: clouds (world frame, m) and tokens ([EMB] last)."""

    object_cloud: torch.Tensor  # (B, P, 3)
    environment_cloud: torch.Tensor  # (B, P, 3)
    local_cloud: torch.Tensor  # (B, P, 3)
    object_tokens: torch.Tensor  # (B, 1 + K, D)
    local_tokens: torch.Tensor  # (B, 1 + K, D)
    global_tokens: torch.Tensor  # (B, 1 + K, D)


def encoder_for(encoder: UniCORN, config: CloudConfig, device: torch.device) -> UniCORN:
    """`encoder` on `device` for inference, checked to take clouds of `config`'s size."""
    if encoder.config.num_points != config.num_points:
        raise ValueError(
            f"the encoder takes {encoder.config.num_points} points, clouds have {config.num_points}"
        )
    return encoder.to(device).eval()


def encode(encoder: UniCORN, points: torch.Tensor, bfloat16: bool) -> torch.Tensor:
    """float32 tokens of clouds (B, P, 3), the encoder's layers in bfloat16 if asked
    (`CloudConfig.encoder_precision`; its patches are found in float32 either way)."""
    with bfloat16_autocast(bfloat16, points.device.type):
        return encoder(points).float()


class Perception:
    """Clouds and UniCORN tokens for B environments, with per-episode caches."""

    def __init__(
        self,
        encoder: UniCORN,
        num_envs: int,
        config: CloudConfig | None = None,
        device: str | torch.device = "cpu",
        seed: int = 0,
    ) -> None:
        self.config = config = config if config is not None else CloudConfig()
        self.device = torch.device(device)
        self.encoder = encoder_for(encoder, config, self.device)
        self.bfloat16 = use_bfloat16(config.encoder_precision, self.device)
        """Whether the encoder's layers run in bfloat16 (`CloudConfig.encoder_precision`)."""
        self.generator = torch.Generator(self.device).manual_seed(seed)
        b, p, s, d = num_envs, config.num_points, config.scene_pool, encoder.config.width
        n, k = encoder.config.num_tokens, config.num_keypoints
        zeros = lambda *shape: torch.zeros(*shape, device=self.device)  # noqa: E731
        self.episode_ids = torch.full((b,), -1, dtype=torch.long, device=self.device)
        """(B,) episode each environment's cache belongs to; -1 before its first scene."""
        self.scene_pool = zeros(b, s, 3)  # (B, S, 3) world frame
        self.environment_cloud = zeros(b, p, 3)  # (B, P, 3) world frame
        self.object_points = zeros(b, p, 3)  # (B, P, 3) object frame
        self.keypoints = zeros(b, k, 3)  # (B, K, 3) object frame
        self.object_tokens = zeros(b, n, d)  # (B, 1 + K, D)
        self.global_tokens = zeros(b, n, d)  # (B, 1 + K, D)
        self.local_clouds = LocalClouds(b, p, config.local_shortlist, self.device)
        """Each environment's shortlist of local-cloud candidates in its pool (derived: not
        in `snapshot`)."""
        self.camera_view: CameraView | None = None
        """Which points the cameras see; None: every point (`CloudConfig.visibility` full)."""
        if config.visibility == "cameras":
            self.camera_view = RigVisibility(
                config.visibility_pixel, config.visibility_depth, config.tolerance
            )
            self.cameras = zeros(b, 4, 3)  # (B, 4, 3) world positions of the rig's cameras
            self.object_normals = zeros(b, p, 3)  # (B, P, 3) object frame, outward

    @property
    def caches(self) -> tuple[str, ...]:
        """The names of the per-episode caches (`CACHES`; with cameras also theirs)."""
        return CACHES if self.camera_view is None else (*CACHES, "cameras", "object_normals")

    @property
    def num_envs(self) -> int:
        """B."""
        return len(self.episode_ids)

    def missing(self, episode_ids: torch.Tensor) -> torch.Tensor:
        """(M,) environments whose cache is not for their current episode (B,) yet."""
        return torch.nonzero(self.episode_ids != episode_ids.to(self.device)).flatten()

    @torch.no_grad()
    def start_episodes(self, scenes: EpisodeScenes) -> None:
        """Sample and encode the scene and object clouds of the K environments starting."""
        config, g = self.config, self.generator
        ids = scenes.env_ids.to(self.device)
        if len(ids) == 0:
            return
        cuboids = Cuboids(*(t.to(self.device) for t in vars(scenes.cuboids).values()))
        crop = workspace_box(cuboids, config.crop_below, config.workspace_height)
        pool = sample_surface(
            cuboids, config.scene_pool, config.grid, config.tolerance, g, crop
        )  # (K, S, 3)
        # Out of place: `Percepts` handed out earlier share these tensors and must not change.
        update = lambda cache, rows: cache.index_copy(0, ids, rows)  # noqa: E731
        if self.camera_view is not None:
            cameras = camera_positions(cuboids.centre[:, TABLE])  # (K, 4, 3)
            seen = self.camera_view.scene(pool, cuboids, cameras)  # (K, S)
            pool = gather(pool, keep(seen, config.scene_pool, g))
            self.cameras = update(self.cameras, cameras)
        environment = corrupt(pool[:, : config.num_points], config.noise_std, config.dropout, g)
        points = scenes.object_points.to(self.device, torch.float32)  # (K, P, 3)
        keypoints = gather(
            points, farthest_point_sample(points, config.num_keypoints)
        )  # (K, 64, 3)
        if self.camera_view is None:
            points = corrupt(points, config.noise_std, config.dropout, g)
        else:  # `step` corrupts what the cameras see
            self.object_normals = update(self.object_normals, outward_normals(points))
        self.scene_pool = update(self.scene_pool, pool)
        self.local_clouds.forget(ids)
        self.environment_cloud = update(self.environment_cloud, environment)
        self.object_points, self.keypoints = (
            update(self.object_points, points),
            update(self.keypoints, keypoints),
        )
        self.global_tokens = update(self.global_tokens, self.encode(environment))
        self.object_tokens = update(self.object_tokens, self.encode(points))
        self.episode_ids = update(self.episode_ids, scenes.episode_ids.to(self.device, torch.long))

    def encode(self, points: torch.Tensor) -> torch.Tensor:
        """Tokens (B, 1 + K, D) of clouds (B, P, 3) at the configured precision."""
        return encode(self.encoder, points, self.bfloat16)

    def snapshot(self) -> tuple[dict[str, torch.Tensor], dict[str, object]]:
        """The per-episode caches (`CACHES`) and the noise generator's state: what a
        perception built from the same encoder and config continues from."""
        arrays = {name: getattr(self, name) for name in self.caches}
        return {**arrays, "generator": self.generator.get_state()}, {}

    def restore(self, arrays: dict[str, np.ndarray], meta: dict[str, object]) -> None:
        """Continue from `snapshot`'s arrays (copied into torch-allocated tensors)."""
        for name in self.caches:
            setattr(self, name, torch.tensor(arrays[name], device=self.device))
        self.local_clouds.forget()
        self.generator.set_state(torch.tensor(arrays["generator"]))

    @torch.no_grad()
    def step(self, object_pose: torch.Tensor, env_ids: torch.Tensor | None = None) -> Percepts:
        """Clouds and tokens with the object at `object_pose`: position (m) and quaternion
        wxyz, (B, 7) for every environment, or (K, 7) for the environments `env_ids` (K,)
        only (a trainer bootstraps the value of the few episodes that timed out)."""
        config = self.config
        rows = slice(None) if env_ids is None else env_ids.to(self.device)
        pose = object_pose.to(self.device, torch.float32)
        keypoints = pose_points(self.keypoints[rows], pose)  # (B, 64, 3)
        pool = self.scene_pool[rows]
        ids = None if env_ids is None else rows
        local = gather(pool, self.local_clouds.nearest(pool, keypoints, ids))  # (B, P, 3)
        local = corrupt(local, config.noise_std, config.dropout, self.generator)
        if self.camera_view is None:
            points, object_tokens = self.object_points[rows], self.object_tokens[rows]
        else:
            points = self._seen_object(rows, pose)
            object_tokens = self.encode(points)
        return Percepts(
            object_cloud=pose_points(points, pose),
            environment_cloud=self.environment_cloud[rows],
            local_cloud=local,
            object_tokens=object_tokens,
            local_tokens=self.encode(local),
            global_tokens=self.global_tokens[rows],
        )

    def _seen_object(self, rows: slice | torch.Tensor, pose: torch.Tensor) -> torch.Tensor:
        """(B, P, 3) the object cloud as the cameras see it at `pose` (B, 7): its visible
        points, resampled to P and corrupted, in the object's frame."""
        config, points = self.config, self.object_points[rows]
        rotation = quaternion_matrix(pose[:, 3:])  # (B, 3, 3)
        normals = torch.einsum("bij,bpj->bpi", rotation, self.object_normals[rows])  # (B, P, 3)
        seen = self.camera_view.object(pose_points(points, pose), normals, self.cameras[rows])
        points = gather(points, keep(seen, config.num_points, self.generator))
        return corrupt(points, config.noise_std, config.dropout, self.generator)
