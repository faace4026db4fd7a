"""DepthFrames on the wire: exact round trip, optional labels, malformed frames refused."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.camera.frames import decode_frames, encode_frames
from hamnet.runtime.tensor import PayloadError, to_tensor
from tests.camera.frames import views
from tests.scripted import wire


def test_frames_round_trip_exactly() -> None:
    sent = views(3)
    message = wire(encode_frames(sent, 7, ["a", "b", "c"]))
    assert message.header.step == 7 and [c.name for c in message.cameras] == ["a", "b", "c"]
    for got, want in zip(decode_frames(message), sent, strict=True):
        for name in ("depth", "labels", "intrinsics", "camera_to_world"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
        assert got.depth.dtype == np.float32 and got.labels.dtype == np.uint8


def test_labels_are_optional() -> None:
    got = decode_frames(wire(encode_frames(views(1, labels=False), 0)))
    assert got[0].labels is None


@pytest.mark.parametrize(
    ("corrupt", "reason"),
    [
        (lambda m: m.ClearField("cameras"), "missing"),
        (lambda m: m.cameras[0].ClearField("intrinsics"), "missing"),
        (lambda m: to_tensor(np.zeros((3, 3), np.uint8), m.cameras[0].labels), "shape"),
        (lambda m: to_tensor(np.full((2, 2), -1.0, np.float32), m.cameras[0].depth), "range"),
        (lambda m: to_tensor(np.full((4, 4), 2.0), m.cameras[0].camera_to_world), "range"),
        (lambda m: to_tensor(np.full((3, 3), np.nan), m.cameras[0].intrinsics), "nonfinite"),
    ],
)
def test_malformed_frames_are_refused_with_a_reason(corrupt, reason) -> None:
    message = encode_frames(views(2), 0)
    corrupt(message)
    with pytest.raises(PayloadError) as error:
        decode_frames(message)
    assert error.value.reason == reason
