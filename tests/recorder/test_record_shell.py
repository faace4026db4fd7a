"""The recorder's payload decoding: payloads stay byte for byte, publish times come from
header stamps, and a contract key carrying garbage is a counted drop."""

from __future__ import annotations

import pytest

from hamnet.recorder.record_shell import decode_payload
from hamnet.runtime.tensor import PayloadError
from tests.recorder.recordings import RAW, STATE, state


def test_payload_is_kept_and_its_header_stamp_is_the_publish_time() -> None:
    payload = state(5, 1234)
    decoded = decode_payload(STATE, payload)
    assert decoded.data is payload and decoded.stamp_ns == 1234


def test_keys_outside_the_contract_are_kept_raw_without_stamp() -> None:
    assert decode_payload(RAW, b"\xff anything").stamp_ns == 0


def test_garbage_on_a_contract_key_is_rejected() -> None:
    with pytest.raises(PayloadError) as error:
        decode_payload(STATE, b"\xff\xff\xff")
    assert error.value.reason == "decode"
