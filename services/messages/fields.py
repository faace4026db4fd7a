"""The decoding step every message module shares: the tensor fields a message carries, each
checked against one batch size, the ones a consumer reads required.

A message module describes its fields once (`Spec`: dtype and trailing shape); consumers
name the fields they read, so a message lacking one is dropped as `missing` where it
matters and accepted where it does not.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from google.protobuf.message import Message

from hamnet.runtime.tensor import field_array


@dataclass(frozen=True)
class Spec:
    """One tensor field: element type and shape after the batch dimension."""

    dtype: type
    tail: tuple[int | None, ...] | None = ()
    """Trailing dimensions (None entries: any size); None: any shape at all, batch
    unchecked (a PolicyAction's arrays, which the safety filter's stage 1 judges)."""
    finite: bool = True
    """Reject NaN and Inf."""


def batch_size(message: Message, specs: Mapping[str, Spec], order: Iterable[str]) -> int | None:
    """B: the declared length of the first field of `order` the message carries, else None.
    Read from the tensor's shape, not its data: `arrays` decodes and checks every field once."""
    for name in order:
        if name in specs and message.HasField(name):
            shape = getattr(message, name).shape
            return int(shape[0]) if shape else None
    return None


def arrays(
    message: Message, specs: Mapping[str, Spec], b: int | None, required: Iterable[str] = ()
) -> dict[str, np.ndarray | None]:
    """Every field of `specs` as a writable array (None when not sent), each (b, *tail).

    Raises:
        ValueError: `required` names a field `specs` does not hold (a programming error).
        PayloadError: `missing` (a required field), `dtype`, `shape`, `nonfinite`.
    """
    required = tuple(required)
    unknown = set(required) - set(specs)
    if unknown:
        raise ValueError(f"{message.DESCRIPTOR.name} has no field {sorted(unknown)}")
    out: dict[str, np.ndarray | None] = dict.fromkeys(specs)
    for name in (*required, *specs):  # the required first: a missing one is reported as such
        if out[name] is None and (name in required or message.HasField(name)):
            spec = specs[name]
            shape = None if spec.tail is None else (b, *spec.tail)
            out[name] = np.array(field_array(message, name, spec.dtype, shape, spec.finite))
    return out
