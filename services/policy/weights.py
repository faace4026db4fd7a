"""Policy weights as safetensors bytes (never pickle), with the metadata that rebuilds the
network: architecture name, model config JSON, version and a format tag.

The same bytes travel in `WeightsAnnouncement.safetensors` and sit in checkpoint files, so a
checkpoint is one announcement written to disk. Loading is checked: metadata present and
known, architecture and config equal to the serving model's, every tensor present with the
right shape and dtype, nothing extra, every value finite. Any failure is a `WeightsError`
saying what is wrong; the target model is untouched then. A network rebuilt from metadata is
first built on the meta device (shapes, no memory) and checked against the file's tensors,
so a config asking for a huge network is refused before anything is allocated.
"""

from __future__ import annotations

import hashlib
import json
import struct
from dataclasses import dataclass
from pathlib import Path

import torch
from safetensors import SafetensorError
from safetensors.torch import load as load_tensors
from safetensors.torch import save as save_tensors
from torch import Tensor

from hamnet.policy.config import ModelConfig
from hamnet.policy.policy import Policy
from hamnet.policy.registry import build
from hamnet.proto.trainer_pb2 import WeightsAnnouncement

FORMAT = "hamnet-policy/1"
"""`format` metadata of every file this module writes."""


class WeightsError(ValueError):
    """Weights that cannot serve: bad bytes, wrong metadata, or tensors that do not fit."""


@dataclass(frozen=True)
class Weights:
    """Decoded weights: what they are for, and the tensors."""

    architecture: str
    config: ModelConfig
    version: int
    tensors: dict[str, Tensor]


HALF = "network"
"""`half` metadata of a file whose network tensors (`network.*`) are stored in float16."""


def to_bytes(policy: Policy, version: int, half: bool = False) -> bytes:
    """safetensors bytes of `policy`'s state dict with its metadata. `half`: the network's
    tensors in float16 (half the bytes: a policy shipped in the package); the input
    statistics and log std stay float32 (a variance can underflow float16)."""
    tensors = {k: v.detach().to("cpu").contiguous() for k, v in policy.state_dict().items()}
    metadata = {
        "format": FORMAT,
        "architecture": policy.architecture,
        "config": policy.config.to_json(),
        "version": str(int(version)),
    }
    if half:
        tensors = {
            k: v.half() if k.startswith(f"{HALF}.") and v.is_floating_point() else v
            for k, v in tensors.items()
        }
        metadata["half"] = HALF
    return save_tensors(tensors, metadata=metadata)


def sha256(data: bytes) -> str:
    """Hex SHA-256 of `data` (what `WeightsAnnouncement.sha256` carries)."""
    return hashlib.sha256(data).hexdigest()


def _metadata(data: bytes) -> dict[str, str]:
    """The `__metadata__` of safetensors bytes (an 8-byte little-endian header size, then the
    JSON header)."""
    if len(data) < 8:
        raise WeightsError(f"not safetensors: {len(data)} bytes")
    (size,) = struct.unpack("<Q", data[:8])
    try:
        header = json.loads(data[8 : 8 + size])
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise WeightsError(f"not safetensors: bad header ({error})") from None
    if not isinstance(header, dict) or not isinstance(header.get("__metadata__"), dict):
        raise WeightsError(
            "safetensors without metadata: architecture, config and version "
            "are needed to rebuild the network"
        )
    return header["__metadata__"]


def from_bytes(data: bytes) -> Weights:
    """Decode safetensors bytes written by `to_bytes`.

    Raises:
        WeightsError: not safetensors, another format, missing or bad metadata.
    """
    meta = _metadata(data)
    if meta.get("format") != FORMAT:
        raise WeightsError(f"format {meta.get('format')!r}, expected {FORMAT!r}")
    try:
        config = ModelConfig.from_json(meta["config"])
        version = int(meta["version"])
        architecture = meta["architecture"]
    except KeyError as error:
        raise WeightsError(f"bad metadata: no {error}") from None
    except (ValueError, TypeError) as error:
        raise WeightsError(f"bad metadata: {error}") from None
    try:
        tensors = load_tensors(data)
    except SafetensorError as error:
        raise WeightsError(f"not safetensors: {error}") from None
    if meta.get("half") == HALF:  # float16 where the metadata says so, float32 to serve
        tensors = {
            k: v.float() if k.startswith(f"{HALF}.") and v.dtype == torch.float16 else v
            for k, v in tensors.items()
        }
    return Weights(architecture, config, version, tensors)


def from_announcement(message: WeightsAnnouncement) -> Weights:
    """The weights a WeightsAnnouncement carries, once its checksum and its metadata agree
    with the safetensors bytes (WeightsError otherwise)."""
    if sha256(message.safetensors) != message.sha256:
        raise WeightsError("sha256 does not match the safetensors bytes")
    weights = from_bytes(message.safetensors)
    if (weights.architecture, weights.version) != (message.architecture, message.version):
        raise WeightsError(
            f"metadata says {weights.architecture!r} version {weights.version}, "
            f"the announcement {message.architecture!r} version {message.version}"
        )
    return weights


def check_action_space(weights: Weights, space: str) -> None:
    """WeightsError unless `weights` act in `space`, the space a filter reads
    (`ModelConfig.action_space`): a policy trained on paddle twists read as joint
    residuals would move the arm somewhere else."""
    if weights.config.action_space != space:
        raise WeightsError(
            f"they act in the {weights.config.action_space!r} action space, the filter "
            f"reads {space!r} (--action-space)"
        )


def check_fits(policy: Policy, weights: Weights) -> None:
    """Raise WeightsError unless `weights` can replace `policy`'s parameters as they are."""
    if weights.architecture != policy.architecture:
        raise WeightsError(
            f"architecture {weights.architecture!r}, serving {policy.architecture!r}"
        )
    if weights.config != policy.config:
        raise WeightsError("model config differs from the serving model's")
    expected = policy.state_dict()
    missing = sorted(set(expected) - set(weights.tensors))
    unexpected = sorted(set(weights.tensors) - set(expected))
    if missing or unexpected:
        raise WeightsError(f"tensors missing {missing[:5]}, unexpected {unexpected[:5]}")
    for name, tensor in weights.tensors.items():
        want = expected[name]
        if tensor.shape != want.shape or tensor.dtype != want.dtype:
            raise WeightsError(
                f"{name}: {tuple(tensor.shape)} {tensor.dtype}, "
                f"expected {tuple(want.shape)} {want.dtype}"
            )
        if tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
            raise WeightsError(f"{name}: NaN or Inf")


def load_into(policy: Policy, weights: Weights) -> None:
    """Copy checked `weights` into `policy` (in place, on its device)."""
    check_fits(policy, weights)
    policy.load_state_dict(weights.tensors)


def policy_from(weights: Weights, device: str | torch.device = "cpu") -> Policy:
    """A policy rebuilt from the weights' metadata and loaded with them, in eval mode.

    The metadata is checked against the tensors on a meta-device build first, so a config
    that asks for more parameters than the file holds allocates nothing.
    """
    check_fits(_described(weights), weights)
    policy = build(weights.architecture, weights.config)
    load_into(policy, weights)
    return policy.to(device).eval()


def _described(weights: Weights) -> Policy:
    """The policy the weights' metadata describes, built on the meta device (shapes only,
    no memory), once its parameter count matches the tensors in the file."""
    try:
        with torch.device("meta"):
            described = build(weights.architecture, weights.config)
    except (ValueError, TypeError) as error:
        raise WeightsError(f"cannot build {weights.architecture!r}: {error}") from None
    expected = sum(t.numel() for t in described.state_dict().values())
    held = sum(t.numel() for t in weights.tensors.values())
    if expected != held:
        raise WeightsError(
            f"the model config describes {expected:,} parameters, the file holds {held:,}"
        )
    return described


def save_checkpoint(path: str | Path, policy: Policy, version: int) -> None:
    """Write a checkpoint (the bytes of a weights announcement) to `path`."""
    Path(path).write_bytes(to_bytes(policy, version))


def read_checkpoint(path: str | Path) -> Weights:
    """Weights from a checkpoint file; WeightsError when it is missing or unusable."""
    try:
        data = Path(path).read_bytes()
    except OSError as error:
        raise WeightsError(f"cannot read checkpoint {path}: {error.strerror}") from None
    try:
        return from_bytes(data)
    except WeightsError as error:
        raise WeightsError(f"checkpoint {path}: {error}") from None
