"""Fully populated random messages of any contract type, for round-trip and wire tests."""

from __future__ import annotations

import numpy as np
from google.protobuf.descriptor import Descriptor, FieldDescriptor
from google.protobuf.message import Message

from hamnet.proto.common_pb2 import Tensor
from hamnet.runtime.tensor import to_tensor

_DTYPES = (np.float32, np.float64, np.int32, np.int64, np.uint8, np.bool_)


def random_tensor(rng: np.random.Generator) -> Tensor:
    """A small tensor of a random supported dtype and shape (finite values)."""
    dtype = _DTYPES[rng.integers(len(_DTYPES))]
    shape = tuple(int(n) for n in rng.integers(1, 5, size=rng.integers(1, 4)))
    return to_tensor((rng.standard_normal(shape) * 10).astype(dtype))


def _scalar(field: FieldDescriptor, rng: np.random.Generator) -> object:
    kind = field.type
    if kind == FieldDescriptor.TYPE_ENUM:
        values = [v.number for v in field.enum_type.values if v.number != 0]
        return int(rng.choice(values))
    if kind == FieldDescriptor.TYPE_STRING:
        return f"s{rng.integers(1_000_000)}"
    if kind == FieldDescriptor.TYPE_BYTES:
        return rng.bytes(int(rng.integers(1, 64)))
    if kind == FieldDescriptor.TYPE_BOOL:
        return True
    if kind in (FieldDescriptor.TYPE_DOUBLE, FieldDescriptor.TYPE_FLOAT):
        return float(np.float32(rng.standard_normal()))
    if kind in (FieldDescriptor.TYPE_UINT32, FieldDescriptor.TYPE_UINT64):
        return int(rng.integers(1, 2**31))
    return int(rng.integers(-(2**31), 2**31))


def fill(message: Message, rng: np.random.Generator) -> Message:
    """Set every field of `message` (recursively) to random values; returns it."""
    if isinstance(message, Tensor):
        message.CopyFrom(random_tensor(rng))
        return message
    descriptor: Descriptor = message.DESCRIPTOR
    for field in descriptor.fields:
        value = getattr(message, field.name)
        entry = field.message_type
        if entry is not None and entry.GetOptions().map_entry:
            value_field = entry.fields_by_name["value"]
            for index in range(2):
                key = f"k{index}"
                if value_field.message_type is not None:
                    fill(value[key], rng)
                else:
                    value[key] = _scalar(value_field, rng)
        elif field.is_repeated:
            for _ in range(2):
                if entry is not None:
                    fill(value.add(), rng)
                else:
                    value.append(_scalar(field, rng))
        elif entry is not None:
            fill(value, rng)
        else:
            setattr(message, field.name, _scalar(field, rng))
    return message


def random_message(message_type: type[Message], seed: int = 0) -> Message:
    """A message of `message_type` with every field set."""
    return fill(message_type(), np.random.default_rng(seed))
