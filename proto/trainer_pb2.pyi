from hamnet.proto import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class WeightsAnnouncement(_message.Message):
    __slots__ = ("header", "version", "architecture", "config_json", "safetensors", "sha256", "env_transitions", "rollout_steps")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    VERSION_FIELD_NUMBER: _ClassVar[int]
    ARCHITECTURE_FIELD_NUMBER: _ClassVar[int]
    CONFIG_JSON_FIELD_NUMBER: _ClassVar[int]
    SAFETENSORS_FIELD_NUMBER: _ClassVar[int]
    SHA256_FIELD_NUMBER: _ClassVar[int]
    ENV_TRANSITIONS_FIELD_NUMBER: _ClassVar[int]
    ROLLOUT_STEPS_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    version: int
    architecture: str
    config_json: str
    safetensors: bytes
    sha256: str
    env_transitions: int
    rollout_steps: int
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., version: _Optional[int] = ..., architecture: _Optional[str] = ..., config_json: _Optional[str] = ..., safetensors: _Optional[bytes] = ..., sha256: _Optional[str] = ..., env_transitions: _Optional[int] = ..., rollout_steps: _Optional[int] = ...) -> None: ...

class Schedule(_message.Message):
    __slots__ = ("header", "env_transitions")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    ENV_TRANSITIONS_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    env_transitions: int
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., env_transitions: _Optional[int] = ...) -> None: ...

class Metrics(_message.Message):
    __slots__ = ("header", "iteration", "scalars")
    class ScalarsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: float
        def __init__(self, key: _Optional[str] = ..., value: _Optional[float] = ...) -> None: ...
    HEADER_FIELD_NUMBER: _ClassVar[int]
    ITERATION_FIELD_NUMBER: _ClassVar[int]
    SCALARS_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    iteration: int
    scalars: _containers.ScalarMap[str, float]
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., iteration: _Optional[int] = ..., scalars: _Optional[_Mapping[str, float]] = ...) -> None: ...

class RolloutChunk(_message.Message):
    __slots__ = ("header", "horizon", "tensors", "teacher_sha256")
    class TensorsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: _common_pb2.Tensor
        def __init__(self, key: _Optional[str] = ..., value: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ...) -> None: ...
    HEADER_FIELD_NUMBER: _ClassVar[int]
    HORIZON_FIELD_NUMBER: _ClassVar[int]
    TENSORS_FIELD_NUMBER: _ClassVar[int]
    TEACHER_SHA256_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    horizon: int
    tensors: _containers.MessageMap[str, _common_pb2.Tensor]
    teacher_sha256: str
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., horizon: _Optional[int] = ..., tensors: _Optional[_Mapping[str, _common_pb2.Tensor]] = ..., teacher_sha256: _Optional[str] = ...) -> None: ...
