"""Configuration of UniCORN pre-training (paper appendix "Details on training UniCORN",
Table tab:pretrain-params): the contact pairs, the dataset on disk, training and evaluation,
one frozen dataclass each.

Values from the paper's table say so in their docstring; the others are this project's
choices, with the reason (docs/pretrain.md lists them all).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from hamnet.perception.config import EncoderConfig
from hamnet.runtime.errors import ConfigError
from hamnet.sim.objects.config import ShapeConfig
from hamnet.sim.scene_config import SceneConfig

EncoderKind = Literal["unicorn", "random-frozen", "pointnet"]
"""unicorn: the perception encoder, trained; random-frozen: the same encoder left at its
random initialisation (only the decoder learns); pointnet: a plain PointNet (baseline)."""


def _check(condition: bool, message: str) -> None:
    if not condition:
        raise ConfigError(message)


@dataclass(frozen=True)
class PairConfig:
    """One contact pair: two shapes moved into touch, then perturbed (paper appendix
    "Contact dataset generation")."""

    num_points: int = 512
    """Surface points per cloud, P (Table tab:network)."""
    cuboid_share: float = 0.3
    """Chance that each shape of a pair is a scene cuboid rather than a library object, so
    the encoder also learns the scene's plates, walls and table."""
    scale: tuple[float, float] = (0.75, 1.5)
    """Range of a library shape's uniform scale (log-uniform): the sim's objects span this
    around the library's sizes; 512 points on a larger shape is a sparser cloud."""
    perturb_translation: float = 0.005
    """Std of the Gaussian translation added after touching, m: a few millimetres, so about
    half of the pairs clip into each other and half narrowly miss."""
    perturb_rotation: float = 0.05
    """Std of the Gaussian rotation (axis-angle) added after touching, rad."""
    position_range: float = 0.3
    """The pair's midpoint is placed uniformly in this cube (+-, m), so no location of the
    frame marks contact."""
    shapes: ShapeConfig = field(default_factory=ShapeConfig)
    """Procedural object kinds and sizes (the sim's object library)."""
    meshes: Path | None = None
    """Folder of mesh files (OBJ, STL, PLY, OFF, GLB, e.g. DexGraspNet's, the paper's source)
    imported into the object library as the sim imports them (`ObjectSet.from_folder`:
    scaled into `shapes.extent`, CoACD convex parts, cached): library objects are drawn from
    them too. None: the procedural kinds only. Nothing is downloaded: the folder must be on
    disk."""
    mesh_share: float = 0.5
    """Chance that a library object is one of the imported meshes (with `meshes`)."""
    scene: SceneConfig = field(default_factory=SceneConfig)
    """Scene distributions the cuboids are drawn from (the sim's scenes)."""

    def __post_init__(self) -> None:
        _check(self.num_points >= 1, f"num_points must be >= 1, got {self.num_points}")
        _check(
            0.0 <= self.cuboid_share <= 1.0,
            f"cuboid_share must be in [0, 1], got {self.cuboid_share}",
        )
        _check(
            0.0 < self.scale[0] <= self.scale[1], f"scale must be 0 < low <= high, got {self.scale}"
        )
        _check(
            self.perturb_translation >= 0 and self.perturb_rotation >= 0,
            "perturbations must be >= 0",
        )
        _check(self.position_range >= 0, "position_range must be >= 0")
        _check(
            0.0 <= self.mesh_share <= 1.0, f"mesh_share must be in [0, 1], got {self.mesh_share}"
        )


@dataclass(frozen=True)
class GenerateConfig:
    """`hamnet pretrain generate`: contact pairs into a chunked folder."""

    out: Path = Path("runs/pretrain/data")
    """Dataset folder: chunk-NNNNN.npz files and manifest.json."""
    pairs: int = 1000
    """Pairs in the dataset (the paper: 500,000)."""
    chunk_size: int = 500
    """Pairs per chunk file; a chunk is the unit of parallelism and of resumption."""
    seed: int = 0
    """Chunk i is drawn from the seed sequence (seed, i): the same seed gives the same data
    whatever the number of workers; another seed gives new shape instances (held-out)."""
    workers: int = 1
    """Processes generating chunks in parallel."""
    report_period_s: float = 10.0
    """Seconds between progress lines."""
    pair: PairConfig = field(default_factory=PairConfig)
    """How each pair is drawn."""

    def __post_init__(self) -> None:
        _check(self.pairs >= 1 and self.chunk_size >= 1, "pairs and chunk_size must be >= 1")
        _check(self.workers >= 1, f"workers must be >= 1, got {self.workers}")

    @property
    def num_chunks(self) -> int:
        """Chunks of the dataset (the last may be short)."""
        return math.ceil(self.pairs / self.chunk_size)


@dataclass(frozen=True)
class AugmentConfig:
    """Augmentation of both clouds of a pair together (Table tab:pretrain-params)."""

    rotation: float = math.pi
    """Rotation angle range +-, rad, about a uniformly random axis (table: (-pi, +pi))."""
    translation: float = 0.1
    """Translation range +- per axis, m (table: (-0.1, +0.1))."""
    log_scale: float = 1.0
    """Scale factor e^U(-log_scale, +log_scale) (table: (e^-1, e^+1))."""
    noise: float = 0.01
    """Std of Gaussian noise on every point, m (table: 0.01)."""


@dataclass(frozen=True)
class OptimConfig:
    """SAM around AdamW with a cosine schedule (Table tab:pretrain-params)."""

    lr: float = 2e-4
    """Base learning rate (table)."""
    min_lr: float = 1e-6
    """Learning rate at the end of the cosine schedule (table)."""
    weight_decay: float = 1e-3
    """AdamW's decoupled weight decay (table)."""
    max_grad_norm: float = 1000.0
    """Gradient norm clip (table)."""
    sam_rho: float = 0.0
    """SAM's neighbourhood radius; 0: plain AdamW. The table names SAM but not rho; at the SAM
    paper's default 0.05 (Foret et al. 2021) the trained UniCORN did worse than its random
    initialisation, and each SAM step costs two passes: with this machine's budget, off by
    default (docs/pretrain.md)."""

    def __post_init__(self) -> None:
        _check(0 < self.min_lr <= self.lr, "need 0 < min_lr <= lr")
        _check(
            self.weight_decay >= 0 and self.max_grad_norm > 0 and self.sam_rho >= 0,
            "need weight_decay >= 0, max_grad_norm > 0, sam_rho >= 0",
        )


@dataclass(frozen=True)
class DecoderConfig:
    """The contact decoder: residual conditional-MLP blocks with conditional batch norm
    (paper appendix "Details on pretraining pipeline")."""

    width: int = 128
    """Hidden width (table: decoder size (128, 128))."""
    blocks: int = 3
    """Residual CMLP blocks (paper: a three-layer conditional MLP)."""

    def __post_init__(self) -> None:
        _check(self.width >= 1 and self.blocks >= 1, "decoder width and blocks must be >= 1")


@dataclass(frozen=True)
class TrainConfig:
    """`hamnet pretrain train`: the contact model on a generated dataset."""

    data: Path = Path("runs/pretrain/data")
    """Training dataset folder (`hamnet pretrain generate --out`)."""
    out: Path = Path("runs/pretrain/unicorn")
    """Run folder: checkpoints, metrics.jsonl."""
    encoder: EncoderKind = "unicorn"
    """Which encoder learns the contacts (random-frozen and pointnet are baselines)."""
    batch_size: int = 32
    """Pairs per step. The paper's 1024 takes minutes per step on 2 CPU cores; 32 gives
    hundreds of steps an hour on one (docs/pretrain.md)."""
    steps: int = 2000
    """Steps of the cosine schedule; training ends there (or at --max-minutes)."""
    max_minutes: float = 0.0
    """Stop (with a checkpoint) after this much training time; 0: no limit."""
    max_pairs: int = 0
    """Use only the first pairs of the dataset; 0: all."""
    encoder_warmup: int = 1200
    """Steps at the start with the encoder frozen, only the decoder learning (then both):
    the decoder first learns to read the random encoder's tokens, and the encoder is tuned
    from there. Trained together from the first step, UniCORN's loss stayed at a plateau
    (0.645) for 4,000 steps at any rate tried; a frozen random encoder's decoder leaves it
    after about 1,000 (docs/pretrain.md). Not in the paper; 0: train both from the start."""
    encoder_lr_scale: float = 1.0
    """The encoder's learning rate as a share of the decoder's (the same cosine schedule)."""
    positive_fraction: float = 0.5
    """Share of the loss on positive patches (table: "positive patch fraction" 0.5;
    `batch.balance_weights`)."""
    seed: int = 0
    """Seed of initialisation, batches and augmentation."""
    resume: bool = False
    """Continue the run in --out from its last checkpoint."""
    log_every: int = 10
    """Steps between metric lines."""
    checkpoint_every: int = 200
    """Steps between checkpoints (one is always written at the end)."""
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    decoder: DecoderConfig = field(default_factory=DecoderConfig)
    architecture: EncoderConfig = field(default_factory=EncoderConfig)
    """The UniCORN architecture (perception's; the shipped weights must fit it)."""

    def __post_init__(self) -> None:
        _check(self.batch_size >= 1 and self.steps >= 1, "batch_size and steps must be >= 1")
        _check(
            self.max_minutes >= 0 and self.max_pairs >= 0, "max_minutes and max_pairs must be >= 0"
        )
        _check(0.0 < self.positive_fraction < 1.0, "positive_fraction must be in (0, 1)")
        _check(
            self.encoder_warmup >= 0 and self.encoder_lr_scale > 0,
            "encoder_warmup must be >= 0 and encoder_lr_scale > 0",
        )
        _check(
            self.log_every >= 1 and self.checkpoint_every >= 1,
            "log_every and checkpoint_every must be >= 1",
        )


@dataclass(frozen=True)
class EvalConfig:
    """`hamnet pretrain eval`: patch contact prediction of trained runs on held-out pairs."""

    data: Path = Path("runs/pretrain/heldout")
    """Held-out dataset (generated with another --seed: shape instances never trained on)."""
    runs: tuple[Path, ...] = (Path("runs/pretrain/unicorn"),)
    """Run folders of `hamnet pretrain train` to compare."""
    out: Path = Path("runs/pretrain/report.json")
    """JSON summary; the PNG (loss curves, ROC) is written next to it."""
    batch_size: int = 64
    """Pairs per forward pass."""
    max_pairs: int = 0
    """Evaluate only the first pairs; 0: all."""
    threshold: float = 0.5
    """Probability above which a patch is predicted in contact."""

    def __post_init__(self) -> None:
        _check(bool(self.runs), "give at least one run folder (--runs)")
        _check(
            self.batch_size >= 1 and self.max_pairs >= 0, "batch_size must be >= 1, max_pairs >= 0"
        )
        _check(0.0 < self.threshold < 1.0, "threshold must be in (0, 1)")
