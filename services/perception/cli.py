"""`hamnet perception`: point clouds and UniCORN tokens for every sim (or bridge) state.

Encodes with the pre-trained UniCORN shipped in the package (`SHIPPED_ENCODER`, made by
`scripts/unicorn_pretrain.py`; docs/pretrain.md) unless `--checkpoint PATH` names another
(a safetensors file of `hamnet pretrain train`, or of `--write-random-checkpoint PATH`).
`--random-init` runs on random weights instead, for tests and ablations; every message then
carries encoder_version 0. Cloud sampling is
configured under `--clouds.<field>` (e.g. `--clouds.noise-std 0.005`), the architecture the
checkpoint must match under `--encoder.<field>`.

`--clouds-from cameras` builds the clouds from the depth frames of `hamnet camera` instead of
the sim's scene message and object pose (the real robot; docs/cameras.md): fused under
`--cameras.<field>`, split by `--segmenter mask` (the frames' labels) or `plane` (table
plane and clustering, `--plane.<field>`); one robot per worker.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal

import torch

from hamnet.perception.checkpoint import (
    RANDOM_VERSION,
    SHIPPED_ENCODER,
    CheckpointError,
    load_checkpoint,
    write_random_checkpoint,
)
from hamnet.perception.config import (
    CameraConfig,
    CloudConfig,
    EncoderConfig,
    PlaneConfig,
    SegmenterName,
)
from hamnet.perception.shell import PORTS, PerceptionLoopConfig, PerceptionShell
from hamnet.perception.unicorn import UniCORN
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.compute import torch_device
from hamnet.runtime.service import Service


@dataclass(frozen=True)
class PerceptionServiceConfig:
    """One perception worker: encoder weights, cloud sampling and the loop."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    checkpoint: Path = SHIPPED_ENCODER
    """Encoder checkpoint (safetensors with architecture and version metadata); default: the
    pre-trained encoder shipped in the package."""
    random_init: bool = False
    """Run on randomly initialised weights instead (tests, ablations); messages say
    encoder_version 0."""
    write_random_checkpoint: Path | None = None
    """Write a random-weights checkpoint (version 0) for `--encoder` to this path and exit."""
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    """The architecture the checkpoint must have."""
    clouds: CloudConfig = field(default_factory=CloudConfig)
    """Environment, object and local cloud sampling."""
    clouds_from: Literal["scene", "cameras"] = "scene"
    """scene: the sim's scene message and privileged object pose; cameras: the depth frames
    on `camera/<w>/frames` (the real robot, or `hamnet camera --source sim`)."""
    cameras: CameraConfig = field(default_factory=CameraConfig)
    """Depth fusion of the camera path (its num_points must equal --clouds.num-points)."""
    segmenter: SegmenterName = "mask"
    """Object from scene, camera path: mask (the frames' labels) or plane (table plane
    removal and clustering, for a real camera)."""
    plane: PlaneConfig = field(default_factory=PlaneConfig)
    """The plane segmenter's options."""
    loop: Annotated[PerceptionLoopConfig, Flattened] = field(default_factory=PerceptionLoopConfig)

    def __post_init__(self) -> None:
        if self.random_init and self.checkpoint != SHIPPED_ENCODER:
            raise ValueError("give either --checkpoint PATH or --random-init, not both")
        if self.cameras.num_points != self.clouds.num_points:
            raise ValueError(
                f"--cameras.num-points ({self.cameras.num_points}) must equal "
                f"--clouds.num-points ({self.clouds.num_points})"
            )


CONFIG = PerceptionServiceConfig
"""The config `hamnet perception` parses (the launcher validates stack files against it)."""


def encoder_from(config: PerceptionServiceConfig) -> tuple[UniCORN, int]:
    """The encoder and its version: the checkpoint's (the shipped one by default), or random
    (`--random-init`).

    Raises:
        CheckpointError: the checkpoint is unusable.
    """
    if config.random_init:
        torch.manual_seed(config.loop.compute.seed)
        return UniCORN(config.encoder), RANDOM_VERSION
    return load_checkpoint(config.checkpoint, config.encoder)


def main(argv: Sequence[str]) -> int:
    """Run `hamnet perception` with command-line arguments `argv`; returns the exit status."""
    config, identity = parse_service(CONFIG, argv, "perception", __doc__, ports=PORTS)
    if config.write_random_checkpoint is not None:
        seed = config.loop.compute.seed
        write_random_checkpoint(config.write_random_checkpoint, config.encoder, seed)
        print(f"wrote random encoder weights (version 0) to {config.write_random_checkpoint}")
        return 0
    try:
        encoder, version = encoder_from(config)
    except CheckpointError as error:
        print(f"hamnet perception: {error}", file=sys.stderr)
        return 2
    with Service(identity, config.common.transport, remap=config.common.remap) as service:
        if config.clouds_from == "cameras":
            return camera_shell(service, encoder, version, config).run()
        return PerceptionShell(service, encoder, version, config.loop, config.clouds).run()


def camera_shell(service: Service, encoder: UniCORN, version: int, config: PerceptionServiceConfig):
    """The shell of `--clouds-from cameras` (imported here: the sim path needs no open3d)."""
    from hamnet.perception.camera_core import CameraPerception
    from hamnet.perception.camera_shell import CameraPerceptionShell
    from hamnet.perception.segmenters import make_segmenter

    segmenter = make_segmenter(config.segmenter, config.cameras, config.plane)
    compute = config.loop.compute
    device = torch_device(compute.device, compute.threads)
    core = CameraPerception(encoder, segmenter, config.clouds, device, compute.seed)
    return CameraPerceptionShell(service, core, version, config.loop)
