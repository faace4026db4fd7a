"""Payload bytes <-> protobuf messages, with the checks every receiver needs.

`decode` parses a payload and validates every Tensor inside it (known dtype, byte count
matching the shape, and, for topics that require it, only finite floats), so that a
malformed payload becomes one `PayloadError` with a reason instead of an exception deep in
a service. Shells on hot paths `parse` instead and check each tensor they use as they turn
it into an array (`from_tensor` with dtype, shape and finiteness): `payload_decoder` makes
the inbox decoder of such a shell from its message type and its decode function.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import TypeVar

from google.protobuf.descriptor import FieldDescriptor
from google.protobuf.message import DecodeError, Message

from hamnet.proto.common_pb2 import Tensor
from hamnet.runtime.tensor import PayloadError, from_tensor

M = TypeVar("M", bound=Message)
T = TypeVar("T")


def encode(message: Message) -> bytes:
    """Serialize a message for the wire."""
    return message.SerializeToString()


def parse(message_type: type[M], payload: bytes) -> M:
    """Parse `payload` as `message_type` without looking inside its tensors.

    For shells that turn the tensors they use into arrays with `from_tensor` and its checks
    right away: each tensor is then copied and checked once, not twice.

    Raises:
        PayloadError: reason `decode` when the bytes are not a valid message.
    """
    message = message_type()
    try:
        message.ParseFromString(payload)
    except (DecodeError, ValueError, RuntimeError) as error:
        raise PayloadError(
            "decode", f"not a {message_type.DESCRIPTOR.full_name}: {error}"
        ) from None
    return message


def payload_decoder(
    message_type: type[M], read: Callable[[M], T] | None = None
) -> Callable[[str, bytes], T]:
    """The inbox decoder (`Inbox.subscribe(decoder=...)`) of a shell's input: the payload
    parsed as `message_type` (`parse`), then `read(message)`, the shell's decode function,
    which checks the tensors it reads and raises PayloadError. None: the parsed message.

    Arguments that change while the shell runs (a batch size the first state fixes) go in
    `read` as a lambda, evaluated for each message.
    """

    def decode_payload(key: str, payload: bytes) -> T:
        message = parse(message_type, payload)
        return message if read is None else read(message)

    return decode_payload


def decode(message_type: type[M], payload: bytes, finite: bool = True) -> M:
    """Parse `payload` as `message_type` and validate every tensor inside it.

    Raises:
        PayloadError: reason `decode` when the bytes are not a valid message, else the
            reason of the first invalid tensor (dtype, shape, nonfinite).
    """
    message = parse(message_type, payload)
    for path, tensor in iter_tensors(message):
        try:
            from_tensor(tensor, finite=finite)
        except PayloadError as error:
            raise PayloadError(error.reason, f"{path}: {error.detail}") from None
    return message


def iter_tensors(message: Message, prefix: str = "") -> Iterator[tuple[str, Tensor]]:
    """Every set Tensor inside `message` (nested, repeated and map fields), with its path."""
    if isinstance(message, Tensor):
        yield prefix.rstrip(".") or "tensor", message
        return
    for field, value in message.ListFields():
        if field.message_type is None:
            continue
        path = f"{prefix}{field.name}"
        if _is_map(field):
            if field.message_type.fields_by_name["value"].message_type is not None:
                for key, item in value.items():
                    yield from iter_tensors(item, f"{path}[{key}].")
        elif field.is_repeated:
            for index, item in enumerate(value):
                yield from iter_tensors(item, f"{path}[{index}].")
        else:
            yield from iter_tensors(value, f"{path}.")


def _is_map(field: FieldDescriptor) -> bool:
    return field.message_type is not None and field.message_type.GetOptions().map_entry
