"""Encoder checkpoints: safetensors files whose metadata records the architecture
(`EncoderConfig` as JSON) and the weights' version.

Version 0 means random weights (never trained): `--random-init` stamps it, and so does a
file written by `write_random_checkpoint`. Pre-training writes versions from 1 up
(`SHIPPED_ENCODER`: where a shipped one goes).
Loading checks the architecture and every tensor's shape and fails with a message that says
what differs: a service never runs silently on weights it was not given.
"""

from __future__ import annotations

from pathlib import Path

import torch
from safetensors import safe_open
from safetensors.torch import save_file

from hamnet.perception.config import EncoderConfig
from hamnet.perception.unicorn import UniCORN

CONFIG_KEY = "hamnet.encoder.config"
VERSION_KEY = "hamnet.encoder.version"
RANDOM_VERSION = 0
"""The version of random (untrained) weights."""
SHIPPED_ENCODER = Path(__file__).resolve().parent / "weights" / "unicorn.safetensors"
"""Where `scripts/unicorn_pretrain.py` ships a pre-trained encoder, with `unicorn.json` saying
how it was made. It ships one only when it beats a random encoder on held-out contact pairs;
none has yet (docs/pretrain.md), so perception and the trainer still need their flags."""


class CheckpointError(ValueError):
    """A checkpoint that cannot be used: missing, unreadable, or for another architecture."""


def save_checkpoint(path: Path, encoder: UniCORN, version: int) -> None:
    """Write the encoder's weights, architecture and `version` (>= 0) to `path`."""
    if version < 0:
        raise ValueError(f"version must be >= 0, got {version}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tensors = {name: t.detach().cpu().contiguous() for name, t in encoder.state_dict().items()}
    metadata = {CONFIG_KEY: encoder.config.to_json(), VERSION_KEY: str(version)}
    save_file(tensors, str(path), metadata=metadata)


def write_random_checkpoint(path: Path, config: EncoderConfig | None = None, seed: int = 0) -> None:
    """A checkpoint of randomly initialised weights (version 0), for tests and smoke runs."""
    torch.manual_seed(seed)
    save_checkpoint(path, UniCORN(config), RANDOM_VERSION)


def read_tensors(path: Path, what: str = "") -> tuple[dict[str, torch.Tensor], dict[str, str]]:
    """Every tensor and the metadata of the safetensors file `path`.

    Raises:
        CheckpointError: the file is unreadable (`what` prefixes its name in the message).
    """
    try:
        with safe_open(str(path), framework="pt") as handle:
            metadata = handle.metadata() or {}
            tensors = {name: handle.get_tensor(name) for name in handle.keys()}  # noqa: SIM118
    except Exception as error:  # noqa: BLE001 (safetensors raises its own types for corrupt files)
        raise CheckpointError(f"{what}{path} is not a readable safetensors file: {error}") from None
    return tensors, metadata


def load_checkpoint(path: Path, expected: EncoderConfig | None = None) -> tuple[UniCORN, int]:
    """The encoder stored at `path` and its version.

    Args:
        path: a file written by `save_checkpoint`.
        expected: the architecture the caller needs; None accepts the file's own.
    Raises:
        CheckpointError: the file is missing or unreadable, lacks the metadata, records
            another architecture than `expected`, or holds tensors of the wrong names or
            shapes.
    """
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"encoder checkpoint {path} does not exist")
    tensors, metadata = read_tensors(path, "encoder checkpoint ")
    if CONFIG_KEY not in metadata or VERSION_KEY not in metadata:
        raise CheckpointError(
            f"{path} lacks {CONFIG_KEY!r}/{VERSION_KEY!r} metadata: not an encoder checkpoint"
        )
    try:
        config = EncoderConfig.from_json(metadata[CONFIG_KEY])
        version = int(metadata[VERSION_KEY])
    except (TypeError, ValueError) as error:
        raise CheckpointError(f"{path} has invalid encoder metadata: {error}") from None
    if expected is not None and config != expected:
        diff = {
            k: (v, getattr(expected, k))
            for k, v in vars(config).items()
            if getattr(expected, k) != v
        }
        raise CheckpointError(
            f"{path} is for another encoder architecture (file, expected): {diff}"
        )
    encoder = UniCORN(config)
    _check_shapes(path, encoder, tensors)
    encoder.load_state_dict(tensors)
    return encoder.eval(), version


def _check_shapes(path: Path, encoder: UniCORN, tensors: dict[str, torch.Tensor]) -> None:
    wanted = {name: tuple(t.shape) for name, t in encoder.state_dict().items()}
    found = {name: tuple(t.shape) for name, t in tensors.items()}
    missing, extra = sorted(wanted.keys() - found.keys()), sorted(found.keys() - wanted.keys())
    wrong = {
        n: (found[n], wanted[n]) for n in wanted.keys() & found.keys() if found[n] != wanted[n]
    }
    if missing or extra or wrong:
        raise CheckpointError(
            f"{path} does not fit the encoder: missing {missing}, unexpected {extra}, "
            f"shapes (file, expected) {wrong}"
        )
