"""The header of a recorded payload, read through the topic contract.

The recorder takes publish times from header stamps and stepped replay takes step numbers
from header steps; both read them here, with the message type the contract gives the key.
"""

from __future__ import annotations

from hamnet.proto.common_pb2 import Header
from hamnet.runtime.codec import parse
from hamnet.runtime.contract import match_key


def header_of(key: str, payload: bytes) -> Header | None:
    """The header of `payload` received on `key`; None for keys outside the contract and
    messages without a header.

    Raises:
        PayloadError: reason `decode` when a contract key's payload is not its message.
    """
    topic = match_key(key)
    if topic is None or topic.message is None:
        return None
    message = parse(topic.message, payload)
    if "header" not in message.DESCRIPTOR.fields_by_name or not message.HasField("header"):
        return None
    return message.header
