"""numpy arrays <-> the `Tensor` message (dtype, shape, raw little-endian bytes).

Decoding makes no copy beyond the one protobuf makes when the bytes field is read: the
array is a read-only view over those bytes. Every check a
receiver needs (dtype, shape, byte count, finiteness) raises `PayloadError` with a reason, so
the runtime can count and drop bad payloads by kind.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from google.protobuf.message import Message

from hamnet.proto.common_pb2 import DType, Tensor

_TO_NUMPY: dict[int, np.dtype] = {
    DType.FLOAT32: np.dtype("<f4"),
    DType.FLOAT64: np.dtype("<f8"),
    DType.FLOAT16: np.dtype("<f2"),
    DType.INT8: np.dtype("i1"),
    DType.INT16: np.dtype("<i2"),
    DType.INT32: np.dtype("<i4"),
    DType.INT64: np.dtype("<i8"),
    DType.UINT8: np.dtype("u1"),
    DType.UINT16: np.dtype("<u2"),
    DType.UINT32: np.dtype("<u4"),
    DType.UINT64: np.dtype("<u8"),
    DType.BOOL: np.dtype("?"),
}
_FROM_NUMPY: dict[np.dtype, int] = {dtype.newbyteorder("="): code for code, dtype in _TO_NUMPY.items()}


class PayloadError(ValueError):
    """A payload that must be dropped; `reason` is the counter it is dropped under."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        """One of: decode, dtype, shape, nonfinite, missing, or a consumer's own (the
        safety service's `space`)."""
        self.detail = detail


def to_tensor(array: np.ndarray, out: Tensor | None = None) -> Tensor:
    """Encode `array` (any shape, a supported dtype) into a Tensor, filling `out` if given."""
    array = np.asarray(array)
    code = _FROM_NUMPY.get(array.dtype.newbyteorder("="))
    if code is None:
        raise TypeError(f"dtype {array.dtype} has no Tensor encoding")
    little = array.astype(_TO_NUMPY[code], copy=False)
    tensor = Tensor() if out is None else out
    tensor.dtype = code
    tensor.shape[:] = little.shape
    tensor.data = np.ascontiguousarray(little).tobytes()
    return tensor


def from_tensor(
    tensor: Tensor,
    dtype: np.dtype | type | None = None,
    shape: Sequence[int | None] | None = None,
    finite: bool = False,
) -> np.ndarray:
    """Decode a Tensor into a read-only numpy view, checking what the caller requires.

    Args:
        tensor: the message.
        dtype: required element type, or None to accept any.
        shape: required shape; None entries accept any size (e.g. `(None, 21)` for (B, 21)).
        finite: reject NaN and Inf in floating-point data.

    Raises:
        PayloadError: with reason dtype, shape or nonfinite.
    """
    np_dtype = _TO_NUMPY.get(tensor.dtype)
    if np_dtype is None:
        raise PayloadError("dtype", f"unknown dtype code {tensor.dtype}")
    if dtype is not None and np_dtype.newbyteorder("=") != np.dtype(dtype).newbyteorder("="):
        raise PayloadError("dtype", f"expected {np.dtype(dtype)}, got {np_dtype}")
    dims = tuple(int(d) for d in tensor.shape)
    # Each read of a bytes field copies it out of the protobuf message: read it once.
    data = tensor.data
    count = math.prod(dims)
    if count * np_dtype.itemsize != len(data):
        raise PayloadError(
            "shape",
            f"shape {dims} of {np_dtype} needs {count * np_dtype.itemsize} bytes, got {len(data)}",
        )
    if shape is not None and (
        len(shape) != len(dims)
        or any(want is not None and want != got for want, got in zip(shape, dims))
    ):
        raise PayloadError("shape", f"expected shape {tuple(shape)}, got {dims}")
    array = np.frombuffer(data, dtype=np_dtype).reshape(dims)
    if finite and not all_finite(array):
        raise PayloadError("nonfinite", f"NaN or Inf in a {dims} {np_dtype} tensor")
    return array


def field_array(
    message: Message,
    name: str,
    dtype: np.dtype | type | None,
    shape: Sequence[int | None] | None,
    finite: bool = True,
) -> np.ndarray:
    """Tensor field `name` of a message as a read-only array (see `from_tensor`), with
    errors that name the field (`RobotState.q: expected shape ...`).

    Args:
        message: a protobuf message with a Tensor field `name`.
        dtype: required element type; None takes float32 or float64, as sent.
        shape: required shape (None entries: any size).
        finite: reject NaN and Inf.
    Raises:
        PayloadError: `missing` when the field is not set, else dtype, shape or nonfinite.
    """
    where = f"{message.DESCRIPTOR.name}.{name}"
    if not message.HasField(name):
        raise PayloadError("missing", f"{where} is not set")
    tensor = getattr(message, name)
    if dtype is None:
        dtype = np.float64 if tensor.dtype == DType.FLOAT64 else np.float32
    try:
        return from_tensor(tensor, dtype, shape, finite)
    except PayloadError as error:
        raise PayloadError(error.reason, f"{where}: {error.detail}") from None


def all_finite(array: np.ndarray) -> bool:
    """True when a floating-point array holds no NaN or Inf (always True for integers)."""
    return array.dtype.kind != "f" or bool(np.isfinite(array).all())
