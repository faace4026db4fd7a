"""Payload decoding: every malformed payload becomes one PayloadError with a reason."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.proto import perception_pb2, sim_pb2, trainer_pb2
from hamnet.runtime.codec import decode, encode, iter_tensors
from hamnet.runtime.tensor import PayloadError, to_tensor


def test_tensors_are_found_in_nested_repeated_and_map_fields() -> None:
    chunk = trainer_pb2.RolloutChunk(horizon=2)
    to_tensor(np.zeros((2, 4), np.float32), chunk.tensors["reward"])
    to_tensor(np.zeros((2, 4), np.bool_), chunk.tensors["done"])
    state = sim_pb2.RobotState()
    to_tensor(np.zeros((4, 7), np.float32), state.privileged.object_pose)
    assert sorted(p for p, _ in iter_tensors(chunk)) == ["tensors[done]", "tensors[reward]"]
    assert [p for p, _ in iter_tensors(state)] == ["privileged.object_pose"]


def test_non_finite_tensor_deep_inside_a_message_is_reported_with_its_path() -> None:
    chunk = trainer_pb2.RolloutChunk()
    to_tensor(np.array([[0.0, np.inf]], np.float32), chunk.tensors["value"])
    with pytest.raises(PayloadError) as error:
        decode(trainer_pb2.RolloutChunk, encode(chunk))
    assert error.value.reason == "nonfinite" and "tensors[value]" in str(error.value)
    assert decode(trainer_pb2.RolloutChunk, encode(chunk), finite=False) == chunk


def test_a_tensor_whose_bytes_disagree_with_its_shape_is_a_shape_error() -> None:
    tokens = perception_pb2.PerceptionTokens()
    to_tensor(np.zeros((2, 512, 3), np.float32), tokens.object_cloud)
    tokens.object_cloud.shape[0] = 3
    with pytest.raises(PayloadError) as error:
        decode(perception_pb2.PerceptionTokens, encode(tokens))
    assert error.value.reason == "shape" and "object_cloud" in str(error.value)


@pytest.mark.parametrize("payload", [b"\xff", b"\x0a\xff\xff\xff\xff\x0f", b"\x08" * 3])
def test_bytes_that_are_not_a_message_are_a_decode_error(payload: bytes) -> None:
    with pytest.raises(PayloadError) as error:
        decode(sim_pb2.RobotState, payload)
    assert error.value.reason == "decode"


def test_truncated_payloads_never_raise_anything_but_payload_error() -> None:
    state = sim_pb2.RobotState()
    to_tensor(np.ones((8, 7), np.float32), state.q)
    to_tensor(np.ones((8, 7), np.float32), state.dq)
    payload = encode(state)
    for end in range(len(payload)):
        try:
            decode(sim_pb2.RobotState, payload[:end])
        except PayloadError:
            pass


def test_parse_leaves_tensor_checks_to_the_shell() -> None:
    """`parse` is for shells that check each tensor they use with `from_tensor`: a
    non-finite tensor passes `parse` and is caught when the shell views it."""
    from hamnet.runtime.codec import parse
    from hamnet.runtime.tensor import from_tensor

    state = sim_pb2.RobotState()
    to_tensor(np.full((2, 7), np.nan, np.float32), state.q)
    parsed = parse(sim_pb2.RobotState, encode(state))
    with pytest.raises(PayloadError) as error:
        from_tensor(parsed.q, np.float32, (None, 7), finite=True)
    assert error.value.reason == "nonfinite"
    with pytest.raises(PayloadError) as error:
        parse(sim_pb2.RobotState, b"\xff\xff")
    assert error.value.reason == "decode"


def test_payload_decoder_parses_then_reads_and_refuses_bytes_that_are_no_message() -> None:
    """The one inbox decoder every shell builds from its message type and decode function."""
    from hamnet.runtime.codec import payload_decoder

    state = sim_pb2.RobotState()
    state.header.step = 7
    read = payload_decoder(sim_pb2.RobotState, lambda message: message.header.step)
    assert read("key", encode(state)) == 7
    assert payload_decoder(sim_pb2.RobotState)("key", encode(state)) == state
    with pytest.raises(PayloadError) as error:
        read("key", b"\xff\xff")
    assert error.value.reason == "decode"
