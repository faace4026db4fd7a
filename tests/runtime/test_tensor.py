"""Tensor encoding: exact round trips, zero-copy decoding and the checks receivers rely on."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hamnet.proto.common_pb2 import DType, Tensor
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.tensor import PayloadError, all_finite, field_array, from_tensor, to_tensor

DTYPES = [np.float32, np.float64, np.float16, np.int8, np.int16, np.int32, np.int64,
          np.uint8, np.uint16, np.uint32, np.uint64, np.bool_]


@given(hnp.arrays(st.sampled_from(DTYPES), hnp.array_shapes(min_dims=0, max_dims=4, max_side=5)))
def test_round_trip_is_exact_for_every_dtype_and_shape(array: np.ndarray) -> None:
    decoded = from_tensor(Tensor.FromString(to_tensor(array).SerializeToString()))
    assert decoded.dtype == array.dtype and decoded.shape == array.shape
    np.testing.assert_array_equal(decoded, array)


def test_big_endian_input_is_stored_little_endian() -> None:
    array = np.arange(6, dtype=">i4").reshape(2, 3)
    tensor = to_tensor(array)
    assert tensor.data == np.arange(6, dtype="<i4").tobytes()
    np.testing.assert_array_equal(from_tensor(tensor), array)


def test_decoding_is_a_read_only_view_over_the_message_bytes() -> None:
    tensor = to_tensor(np.ones((64, 512, 3), np.float32))
    decoded = from_tensor(tensor)
    assert not decoded.flags.writeable
    assert not decoded.flags.owndata  # a view, not a copy


def test_required_dtype_and_shape_are_enforced() -> None:
    tensor = to_tensor(np.zeros((4, 21), np.float32))
    assert from_tensor(tensor, np.float32, (None, 21)).shape == (4, 21)
    with pytest.raises(PayloadError) as error:
        from_tensor(tensor, np.float64)
    assert error.value.reason == "dtype"
    for shape in [(None, 7), (4,), (None, 21, 1)]:
        with pytest.raises(PayloadError) as error:
            from_tensor(tensor, shape=shape)
        assert error.value.reason == "shape"


def test_byte_count_must_match_the_shape() -> None:
    tensor = to_tensor(np.zeros((4, 3), np.float32))
    tensor.data = tensor.data[:-1]
    with pytest.raises(PayloadError, match="needs 48 bytes, got 47"):
        from_tensor(tensor)
    tensor.shape[:] = [2**40, 2**40]
    with pytest.raises(PayloadError):
        from_tensor(tensor)


def test_unknown_dtype_codes_are_rejected() -> None:
    tensor = Tensor(dtype=DType.DTYPE_UNSPECIFIED, shape=[1], data=b"\0")
    with pytest.raises(PayloadError) as error:
        from_tensor(tensor)
    assert error.value.reason == "dtype"


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_values_are_rejected_only_when_asked(bad: float) -> None:
    array = np.zeros((3, 5), np.float32)
    array[2, 4] = bad
    tensor = to_tensor(array)
    assert np.isnan(from_tensor(tensor)[2, 4]) == np.isnan(bad)
    with pytest.raises(PayloadError) as error:
        from_tensor(tensor, finite=True)
    assert error.value.reason == "nonfinite"


def test_all_finite_ignores_integers_and_empty_arrays() -> None:
    assert all_finite(np.array([], np.float32))
    assert all_finite(np.array([2**62], np.int64))
    assert all_finite(np.array([np.finfo(np.float32).max, -np.finfo(np.float32).max], np.float32))
    assert not all_finite(np.array([1.0, np.nan], np.float64))


def test_field_array_names_the_field_in_every_error() -> None:
    """Shells decode fields with `field_array`: a missing field is its own reason, and the
    message says which field of which message broke, whatever the reason."""
    message = RobotState()
    with pytest.raises(PayloadError) as error:
        field_array(message, "q", np.float32, (None, 7))
    assert error.value.reason == "missing" and "RobotState.q" in error.value.detail
    to_tensor(np.array([[np.nan] * 7]), message.q)  # float64 on the wire
    assert field_array(message, "q", None, (1, 7), finite=False).dtype == np.float64
    for dtype, shape, reason in ((np.float32, (1, 7), "dtype"), (None, (2, 7), "shape"),
                                 (None, (1, 7), "nonfinite")):  # fmt: skip
        with pytest.raises(PayloadError) as error:
            field_array(message, "q", dtype, shape)
        assert error.value.reason == reason and error.value.detail.startswith("RobotState.q: ")
