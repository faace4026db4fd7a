"""A rollout (or DAgger's demonstrations) <-> a RolloutChunk message: the wire format in
which rollout workers and the policy service stream what acting recorded to the trainer.

Every field of the rollout travels as a named tensor; the policy inputs (a tree of
dataclasses) under dotted names (`inputs.observation.base`). What stays the same for a
whole episode (object and global tokens, the EnvCode) is sent once per distinct row with an
index (`inputs.object_tokens` and `inputs.object_tokens#index`): within a chunk of T steps
each environment repeats them T times. Decoding checks every name, shape and dtype against
the reader's policy and raises `PayloadError` (counted and dropped by the inbox) for a chunk
that does not fit, so a bad chunk never reaches an update. It lives with the policy, below
the trainer, because the policy service writes chunks too. Shapes: T steps, B environments.
"""

from __future__ import annotations

import dataclasses
import typing

import numpy as np
import torch
from torch import Tensor

from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import VELOCITY_WIDTH
from hamnet.policy.policy import Policy
from hamnet.policy.rollout_record import RolloutLike
from hamnet.proto.common_pb2 import Header
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime.tensor import PayloadError, from_tensor, to_tensor
from hamnet.runtime.trees import take_rows
from hamnet.task.rewards import REWARD_NAMES

PER_EPISODE = ("object_tokens", "global_tokens", "env_code")
"""Input fields constant within an episode: sent once per distinct row."""

INDEX = "#index"
"""Suffix of the (T * B,) row index of a field sent once per distinct row."""


def flatten(tree: object, prefix: str) -> dict[str, Tensor]:
    """Every tensor leaf of a dataclass tree by dotted name (None leaves are left out)."""
    if tree is None:
        return {}
    if isinstance(tree, Tensor):
        return {prefix: tree}
    out: dict[str, Tensor] = {}
    for field in dataclasses.fields(tree):
        out.update(flatten(getattr(tree, field.name), f"{prefix}.{field.name}"))
    return out


def unflatten(cls: type, tensors: dict[str, Tensor], prefix: str) -> object:
    """The dataclass `cls` rebuilt from `flatten`'s names; absent leaves become None."""
    hints = typing.get_type_hints(cls)
    values = {}
    for field in dataclasses.fields(cls):
        name = f"{prefix}.{field.name}"
        kind = hints[field.name]
        if dataclasses.is_dataclass(kind):
            values[field.name] = unflatten(kind, tensors, name)
        else:
            values[field.name] = tensors.get(name)
    return cls(**values)


def _rows_once(rows: Tensor) -> tuple[Tensor, Tensor]:
    """(distinct rows (U, ...), index (N,) int32) with distinct[index] == rows."""
    distinct, index = torch.unique(rows.reshape(len(rows), -1), dim=0, return_inverse=True)
    return distinct.reshape(-1, *rows.shape[1:]), index.to(torch.int32)


def encode_rollout(batch: RolloutLike, version: int, step: int) -> RolloutChunk:
    """The chunk of a rollout (or of DAgger's demonstrations) `batch`, acted by weights
    `version`; `step` counts the producer's chunks."""
    horizon = len(batch.dones)
    chunk = RolloutChunk(header=Header(step=step, policy_version=version), horizon=horizon)
    for field in dataclasses.fields(batch):
        value = getattr(batch, field.name)
        if field.name != "inputs" and value is not None:
            to_tensor(value.numpy(), chunk.tensors[field.name])
    for name, rows in flatten(batch.inputs, "inputs").items():
        if name.rsplit(".", 1)[-1] in PER_EPISODE:
            rows, index = _rows_once(rows)
            to_tensor(index.numpy(), chunk.tensors[name + INDEX])
        to_tensor(rows.numpy(), chunk.tensors[name])
    return chunk


def leaf_names(cls: type, prefix: str) -> list[str]:
    """Every dotted leaf name a tree of dataclass `cls` can have (see `flatten`)."""
    hints = typing.get_type_hints(cls)
    names = []
    for field in dataclasses.fields(cls):
        kind, name = hints[field.name], f"{prefix}.{field.name}"
        names += leaf_names(kind, name) if dataclasses.is_dataclass(kind) else [name]
    return names


def _array(chunk: RolloutChunk, name: str, dtype: type, shape: tuple[int | None, ...]) -> Tensor:
    """One named tensor of the chunk, checked; PayloadError names it."""
    try:
        array = from_tensor(chunk.tensors[name], dtype, shape, finite=True)
    except PayloadError as error:
        raise PayloadError(error.reason, f"RolloutChunk {name}: {error.detail}") from None
    return torch.tensor(array)  # torch's allocator aligns like the learner's own tensors


def _per_episode(name: str) -> bool:
    return name.rsplit(".", 1)[-1] in PER_EPISODE


def decode_batch(
    chunk: RolloutChunk,
    kind: type[RolloutLike],
    shapes: dict[str, str],
    flags: tuple[str, ...],
    policy: Policy,
    optional: dict[str, str] | None = None,
) -> RolloutLike:
    """The `kind` in `chunk`, checked for `policy` as `decode_rollout` says; `shapes`: its
    fields other than the inputs by their dimensions' letters (T, B, A, R, V the object's
    velocity; one (T, B, A) field, which the policy's check evaluates), `flags`: those that
    are bool, `optional`: fields a chunk may leave out (None then), by their letters."""
    steps, terms, action_dim = chunk.horizon, len(REWARD_NAMES), policy.config.action_dim
    missing = [name for name in shapes if name not in chunk.tensors]
    if missing or steps < 1:
        raise PayloadError("missing", f"RolloutChunk lacks {missing} (horizon {steps})")
    batch = int(chunk.tensors["dones"].shape[-1]) if chunk.tensors["dones"].shape else 0
    sizes = {"T": steps, "B": batch, "A": action_dim, "R": terms, "V": VELOCITY_WIDTH}
    optional = optional or {}
    fields = {
        name: _array(
            chunk, name, bool if name in flags else np.float32, tuple(sizes[d] for d in dims)
        )
        for name, dims in {**shapes, **optional}.items()
        if name in shapes or name in chunk.tensors
    }
    names = leaf_names(PolicyInputs, "inputs")
    known = set(shapes) | set(optional) | set(names) | {n + INDEX for n in names if _per_episode(n)}
    unknown = sorted(set(chunk.tensors) - known)
    if unknown:
        raise PayloadError("shape", f"RolloutChunk has unknown tensors {unknown[:5]}")
    rows, inputs = steps * batch, {}
    for name in (n for n in names if n in chunk.tensors):
        if _per_episode(name):
            index = _array(chunk, name + INDEX, np.int32, (rows,)).long()
            distinct = _array(chunk, name, np.float32, (None,) * len(chunk.tensors[name].shape))
            if len(index) and (index.min() < 0 or index.max() >= len(distinct)):
                raise PayloadError("shape", f"RolloutChunk {name}{INDEX} points outside its rows")
            inputs[name] = distinct[index]
        else:
            inputs[name] = _array(
                chunk, name, np.float32, (rows,) + (None,) * (len(chunk.tensors[name].shape) - 1)
            )
    decoded = kind(inputs=unflatten(PolicyInputs, inputs, "inputs"), **fields)
    actions = fields[next(name for name, dims in shapes.items() if dims == "TBA")]
    first = torch.zeros(1, dtype=torch.long)
    try:
        with torch.no_grad():
            policy.evaluate(take_rows(decoded.inputs, first), actions[0, :1])
    except (ValueError, RuntimeError, TypeError) as error:
        raise PayloadError("shape", f"RolloutChunk inputs do not fit the policy: {error}") from None
    return decoded
