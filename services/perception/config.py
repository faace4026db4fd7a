"""Configuration of the perception core: cloud sampling, the UniCORN encoder and the depth
camera path, one frozen dataclass each (paper appendix "Point cloud sampling process",
Table tab:network, and the real-robot setup with four RealSense D435 cameras).

`EncoderConfig` is also the architecture record written into every encoder checkpoint: a
checkpoint loads only into an encoder built from an equal config.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, replace
from typing import Literal, get_args

from hamnet.runtime.compute import Precision

Visibility = Literal["full", "cameras"]
"""Which surface the clouds show: all of it, or what the four cameras see."""

STUDENT_NOISE_STD = 0.01
"""Cloud noise of the student, m: the one cloud noise the paper states, its pretraining
"Noise augmentation" 0.01 (Table tab:pretrain-params), which the shared UniCORN encoder is
trained to tolerate. The paper gives no noise for the student's clouds."""
STUDENT_DROPOUT = 0.1
"""Point dropout of the student: our choice (holes of a depth camera); the paper states
none."""


def _at_least(owner: object, minimum: float, *names: str) -> None:
    for name in names:
        value = getattr(owner, name)
        if not value >= minimum:
            raise ValueError(f"{type(owner).__name__}.{name} must be >= {minimum}, got {value}")


@dataclass(frozen=True)
class CloudConfig:
    """Clouds in simulation: environment (global), object and local (focal) clouds."""

    num_points: int = 512
    """Points per cloud, P (Table tab:network)."""
    grid: int = 2
    """Each cuboid face is split into grid x grid cells of two triangles each before culling:
    finer grids cull more of a partly covered face up front so fewer samples are rejected,
    but cost more to test (on a 2-core CPU, 2 beat 8 by 10x for 64 scenes of 512 points)."""
    scene_pool: int = 4096
    """Scene points sampled per environment at reset; the global cloud is the first
    `num_points` of them (a uniform subset of a uniform sample) and the local cloud picks
    among all of them, so it stays dense near the object."""
    num_keypoints: int = 64
    """FPS keypoints of the object cloud that the local cloud is gathered around."""
    local_shortlist: int = 1024
    """Pool points each environment keeps as candidates of its next local clouds
    (`hamnet.perception.local_cloud`: the same points, ranked over the shortlist while it
    provably holds them); 0 ranks the whole pool every step. Measured on 64 pools of the
    easy stage, one thread, objects moving 2, 5, 10, 20 mm a step: 1024 ranked 1, 6, 14, 28%
    of the steps in full again, 7.9-14.8 ms a step against 15 ms for whole pools; 768 was
    cheaper only under 5 mm, 1536 cost 10-14 ms at any pace."""
    noise_std: float = 0.0
    """Gaussian noise added to every published cloud point, m (0: none; the student and the
    real robot see noisy clouds)."""
    dropout: float = 0.0
    """Share of each cloud's points replaced by copies of its other points (0: none): holes
    as a depth camera leaves them, with the cloud size kept."""
    tolerance: float = 1e-5
    """A point closer than this to another cuboid (m) counts as on its boundary."""
    crop_below: float = 0.01
    """The scene clouds keep the surface from this far under the table top, m (authors'
    ham/src/ham/env/episode/scene_cloud.py:53, `base_height - 0.01`)."""
    workspace_height: float = 0.65
    """... up to this far above it, m, within the table's footprint: the tallest case, ceiling
    0.5 m on a 0.15 m plate (authors' tabletop_with_object_scene_v3.py:386-387)."""

    encoder_precision: Precision = "auto"
    """How UniCORN's layers run (`hamnet.runtime.compute.Precision`): "auto" is bfloat16 on
    a CPU with native bfloat16 and float32 elsewhere; the patches' neighbours are ranked in
    float32 either way. On the shipped encoder and 64 local clouds of the easy stage,
    bfloat16 tokens were within 0.5% (relative norm) of float32's, every token's cosine
    above 0.9999, and the layers 2.3x faster on one thread."""

    visibility: Visibility = "full"
    """"full": every surface (the teacher); "cameras": only the points one of the four
    cameras of the paper's rig sees (the student; `hamnet.perception.visibility`): the
    scene once per episode, the object every step (its tokens too)."""
    visibility_pixel: float = 0.5
    """Object z-buffer pixel, in point spacings (`visibility.object_visible`)."""
    visibility_depth: float = 2.0
    """Object z-buffer depth tolerance, in point spacings: with the pixel above the rule
    agrees with exact visibility on 91-97% of the points of boxes (open3d's HPR: 96-98%,
    at eight times the cost per step)."""

    def __post_init__(self) -> None:
        _at_least(self, 1, "num_points", "grid", "num_keypoints")
        if self.encoder_precision not in get_args(Precision):
            raise ValueError(
                f"encoder_precision must be one of {get_args(Precision)}, "
                f"got {self.encoder_precision!r}"
            )
        if self.visibility not in get_args(Visibility):
            raise ValueError(
                f"visibility must be one of {get_args(Visibility)}, got {self.visibility!r}"
            )
        if not (self.visibility_pixel > 0.0 and self.visibility_depth >= 0.0):
            raise ValueError("visibility_pixel must be > 0 and visibility_depth >= 0")
        if self.local_shortlist and not self.num_points <= self.local_shortlist:
            raise ValueError(
                f"local_shortlist ({self.local_shortlist}) must be 0 or >= num_points "
                f"({self.num_points})"
            )
        if self.scene_pool < self.num_points:
            raise ValueError(
                f"scene_pool ({self.scene_pool}) must be >= num_points ({self.num_points})"
            )
        if self.crop_below < 0.0 or self.workspace_height <= 0.0:
            raise ValueError("crop_below must be >= 0 and workspace_height > 0")
        if self.noise_std < 0.0 or not 0.0 <= self.dropout < 1.0 or self.tolerance < 0.0:
            raise ValueError("noise_std and tolerance must be >= 0 and dropout in [0, 1)")


def student_clouds(config: CloudConfig | None = None) -> CloudConfig:
    """`config` (default: the defaults) as the student sees clouds: what the cameras see,
    with `STUDENT_NOISE_STD` and `STUDENT_DROPOUT`."""
    config = config if config is not None else CloudConfig()
    return replace(
        config, visibility="cameras", noise_std=STUDENT_NOISE_STD, dropout=STUDENT_DROPOUT
    )


@dataclass(frozen=True)
class EncoderConfig:
    """The UniCORN geometry encoder (paper Fig. pretraining_network, Table tab:network)."""

    num_points: int = 512
    """Points per input cloud."""
    num_patches: int = 16
    """Patch centres chosen by farthest-point sampling."""
    patch_size: int = 32
    """Points per patch (k nearest neighbours of its centre)."""
    width: int = 128
    """Token width D."""
    depth: int = 4
    """Pre-LN transformer layers."""
    heads: int = 4
    """Self-attention heads."""
    mlp_ratio: int = 2
    """Hidden width of each transformer layer's MLP, in multiples of `width`."""
    tokenizer_hidden: tuple[int, ...] = (256, 256)
    """Hidden widths of the MLP over each flattened patch (the authors' MLPPatchEncoder,
    ham/models/cloud/point_mae.py:772)."""
    frequencies: int = 16
    """Sinusoidal frequencies per coordinate of the positional embedding of the centres."""
    max_wavelength: float = 4.0
    """Longest wavelength of the positional embedding, m (the shortest is 4 mm: from the
    size of a workspace down to below a patch's spacing)."""

    def __post_init__(self) -> None:
        _at_least(self, 1, "num_patches", "patch_size", "width", "depth", "heads", "mlp_ratio")
        _at_least(self, 1, "frequencies")
        hidden = self.tokenizer_hidden
        if not isinstance(hidden, tuple) or not hidden or min(hidden) < 1:
            raise ValueError(
                f"tokenizer_hidden must be a tuple of positive widths (the MLP over "
                f"the flattened patch), got {hidden!r}"
            )
        if self.width % self.heads:
            raise ValueError(f"width ({self.width}) must be divisible by heads ({self.heads})")
        if self.patch_size > self.num_points or self.num_patches > self.num_points:
            raise ValueError("patch_size and num_patches must be <= num_points")

    @property
    def num_tokens(self) -> int:
        """Tokens per cloud: one per patch, then [EMB]."""
        return self.num_patches + 1

    def to_json(self) -> str:
        """The architecture as canonical JSON (stored in checkpoint metadata)."""
        return json.dumps(asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> EncoderConfig:
        """Inverse of `to_json`; unknown or missing fields raise TypeError."""
        values = json.loads(text)
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


@dataclass(frozen=True)
class CameraConfig:
    """Depth cameras to clouds (the bridge's path): fuse, crop, filter, split, resample."""

    workspace_min: tuple[float, float, float] = (-0.2, -1.0, -0.2)
    """Lower corner of the workspace crop in the world frame, m."""
    workspace_max: tuple[float, float, float] = (1.6, 1.0, 1.5)
    """Upper corner of the workspace crop, m."""
    max_depth: float = 3.0
    """Depth readings beyond this are discarded, m (D435 noise grows with distance)."""
    voxel_size: float = 0.005
    """Voxel edge of the downsampling that evens out the density of overlapping views, m."""
    outlier_neighbors: int = 16
    """Neighbours of the statistical outlier removal."""
    outlier_std_ratio: float = 2.0
    """Points farther than mean + ratio * std from their neighbours are removed."""
    num_points: int = 512
    """Points of each output cloud (object, scene) after resampling."""

    def __post_init__(self) -> None:
        if any(lo >= hi for lo, hi in zip(self.workspace_min, self.workspace_max)):
            raise ValueError("workspace_min must be below workspace_max on every axis")
        if not (self.max_depth > 0 and self.voxel_size > 0 and self.outlier_std_ratio > 0):
            raise ValueError("max_depth, voxel_size and outlier_std_ratio must be > 0")
        _at_least(self, 1, "outlier_neighbors", "num_points")


SegmenterName = Literal["mask", "plane"]
"""How the camera path tells object from scene (`hamnet.perception.segmenters`)."""


@dataclass(frozen=True)
class PlaneConfig:
    """Table-plane removal and clustering (`PlaneSegmenter`)."""

    distance: float = 0.01
    """RANSAC inlier distance to the table plane, m (D435 depth noise at 1 m is a few mm)."""
    iterations: int = 500
    """RANSAC iterations."""
    min_height: float = 0.01
    """Points less than this above the plane belong to the table, m."""
    cluster_eps: float = 0.02
    """DBSCAN neighbourhood radius, m (a few voxels of `CameraConfig.voxel_size`)."""
    cluster_min_points: int = 10
    """DBSCAN core point threshold."""
    seed: int = 0
    """Seed of RANSAC's sampling (open3d's global random generator)."""

    def __post_init__(self) -> None:
        if not (self.distance > 0 and self.min_height >= 0 and self.cluster_eps > 0):
            raise ValueError("distance and cluster_eps must be > 0, min_height >= 0")
        if self.iterations < 1 or self.cluster_min_points < 1:
            raise ValueError("iterations and cluster_min_points must be >= 1")
