"""The contact dataset on disk: `chunk-NNNNN.npz` files of `chunk_size` pairs each and a
`manifest.json` that records how they were drawn.

Chunk i is drawn from numpy's seed sequence (seed, i), so the data depend on the seed only,
not on the number of workers or on the order chunks finish in. A chunk is written to a
temporary name and renamed when complete, so after an interruption `generate` skips every
chunk already there (and of the right length) and draws only the rest. Loading refuses a
dataset whose chunks are not all there.

Arrays of a chunk (n pairs, P points): points_a, points_b (n, P, 3) float32 m; labels_a,
labels_b (n, P) bool (inside the other shape); colliding (n,) bool; kind_a, kind_b (n,) str.
"""

from __future__ import annotations

import json
import logging
import multiprocessing
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from hamnet.pretrain.config import GenerateConfig, PairConfig
from hamnet.pretrain.pairs import sample_pair
from hamnet.pretrain.progress import Progress
from hamnet.runtime.errors import ConfigError

log = logging.getLogger(__name__)

MANIFEST = "manifest.json"
FORMAT = 1
"""Version of the layout; a manifest of another one is refused."""
FIELDS = ("points_a", "points_b", "labels_a", "labels_b", "colliding", "kind_a", "kind_b")


def chunk_path(folder: Path, index: int) -> Path:
    return folder / f"chunk-{index:05d}.npz"


def chunk_length(config: GenerateConfig, index: int) -> int:
    """Pairs in chunk `index` (the last one holds the rest)."""
    return min(config.chunk_size, config.pairs - index * config.chunk_size)


def draw_chunk(pair: PairConfig, seed: int, index: int, length: int) -> dict[str, np.ndarray]:
    """The arrays of chunk `index`: `length` pairs drawn from the seed sequence (seed, index)."""
    rng = np.random.default_rng([seed, index])
    pairs = [sample_pair(rng, pair) for _ in range(length)]
    return {name: np.stack([getattr(p, name) for p in pairs]) for name in FIELDS}


def write_chunk(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write atomically: a reader (or a resumed run) never sees half a chunk."""
    partial = path.with_suffix(".partial")
    with open(partial, "wb") as handle:
        np.savez_compressed(handle, **arrays)
    os.replace(partial, path)


def read_chunk(path: Path) -> dict[str, np.ndarray]:
    """The arrays of one chunk (no pickle)."""
    with np.load(path, allow_pickle=False) as data:
        return {name: data[name] for name in FIELDS}


def _complete(path: Path, length: int) -> bool:
    try:
        with np.load(path, allow_pickle=False) as data:
            return len(data["colliding"]) == length
    except (OSError, ValueError, KeyError):
        return False  # unreadable: drawn again


def _identity(config: GenerateConfig) -> dict:
    """What a resumed run must share with the one that started the folder: what draws the
    pairs (without imported meshes, their share draws nothing, and folders made before the
    option existed stay valid)."""
    pair = json.loads(json.dumps(asdict(config.pair), default=str))
    if config.pair.meshes is None:
        del pair["meshes"], pair["mesh_share"]
    return {"format": FORMAT, "seed": config.seed, "chunk_size": config.chunk_size, "pair": pair}


def _job(args: tuple[PairConfig, int, int, int, str]) -> int:
    """Draw and write one chunk; returns its pairs (`summarise` reads the balance once all
    chunks, also those of an earlier run, are there)."""
    pair, seed, index, length, path = args
    write_chunk(Path(path), draw_chunk(pair, seed, index, length))
    return length


def generate(config: GenerateConfig) -> dict:
    """Draw every missing chunk of the dataset in `config.out`; returns the manifest.

    Raises:
        ConfigError: the folder holds a dataset drawn with another seed, chunk size or pair
            configuration.
    """
    folder = Path(config.out)
    folder.mkdir(parents=True, exist_ok=True)
    manifest_path = folder / MANIFEST
    identity = _identity(config)
    if manifest_path.is_file():
        previous = json.loads(manifest_path.read_text())
        if {k: previous.get(k) for k in identity} != identity:
            raise ConfigError(
                f"{folder} holds a dataset drawn with another seed, chunk size or "
                "pair configuration: give another --out"
            )
    manifest_path.write_text(
        json.dumps({**identity, "pairs": config.pairs, "complete": False}, indent=1)
    )
    jobs = [
        (config.pair, config.seed, i, chunk_length(config, i), str(chunk_path(folder, i)))
        for i in range(config.num_chunks)
        if not _complete(chunk_path(folder, i), chunk_length(config, i))
    ]
    done = config.pairs - sum(job[3] for job in jobs)
    if done:
        log.info(
            "resuming: %d of %d chunks already there",
            config.num_chunks - len(jobs),
            config.num_chunks,
        )
    progress = Progress("generate", config.pairs, "pairs", config.report_period_s, done)
    if config.workers == 1:
        for job in jobs:
            progress.advance(_job(job))
    else:
        with multiprocessing.get_context("spawn").Pool(config.workers) as pool:
            for pairs in pool.imap_unordered(_job, jobs):
                progress.advance(pairs)
    manifest = {**identity, "pairs": config.pairs, "complete": True, **summarise(folder)}
    manifest_path.write_text(json.dumps(manifest, indent=1))
    return manifest


def summarise(folder: Path) -> dict:
    """Balance of a finished dataset: share of colliding pairs and of positive points."""
    chunks = [read_chunk(p) for p in sorted(folder.glob("chunk-*.npz"))]
    colliding = np.concatenate([c["colliding"] for c in chunks])
    labels = np.concatenate([np.concatenate([c["labels_a"], c["labels_b"]]) for c in chunks])
    return {
        "chunks": len(chunks),
        "colliding_share": float(colliding.mean()),
        "positive_point_share": float(labels.mean()),
    }


@dataclass(frozen=True, eq=False)
class PairArrays:
    """A whole dataset (or its first pairs) in memory."""

    points_a: np.ndarray
    """(N, P, 3) float32, m."""
    points_b: np.ndarray
    labels_a: np.ndarray
    """(N, P) bool."""
    labels_b: np.ndarray
    colliding: np.ndarray
    """(N,) bool."""

    def __len__(self) -> int:
        return len(self.colliding)


def load_pairs(folder: Path, max_pairs: int = 0) -> PairArrays:
    """The pairs of a complete dataset, the first `max_pairs` of them if > 0.

    Raises:
        ConfigError: no dataset there, or an unfinished one.
    """
    folder = Path(folder)
    manifest_path = folder / MANIFEST
    if not manifest_path.is_file():
        raise ConfigError(
            f"{folder} is not a contact dataset (no {MANIFEST}): run `hamnet pretrain generate`"
        )
    manifest = json.loads(manifest_path.read_text())
    if manifest.get("format") != FORMAT or not manifest.get("complete"):
        raise ConfigError(
            f"{folder} is unfinished or of another format: run `hamnet pretrain generate` "
            "with the same flags to finish it"
        )
    wanted = manifest["pairs"] if max_pairs <= 0 else min(max_pairs, manifest["pairs"])
    chunks = [
        read_chunk(chunk_path(folder, i)) for i in range(-(-wanted // manifest["chunk_size"]))
    ]
    joined = {name: np.concatenate([c[name] for c in chunks])[:wanted] for name in FIELDS[:5]}
    return PairArrays(**joined)
