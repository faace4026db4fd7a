from hamnet.proto import common_pb2 as _common_pb2
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class PerceptionTokens(_message.Message):
    __slots__ = ("header", "episode_ids", "object_cloud", "environment_cloud", "local_cloud", "object_tokens", "local_tokens", "global_tokens", "encoder_version")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    EPISODE_IDS_FIELD_NUMBER: _ClassVar[int]
    OBJECT_CLOUD_FIELD_NUMBER: _ClassVar[int]
    ENVIRONMENT_CLOUD_FIELD_NUMBER: _ClassVar[int]
    LOCAL_CLOUD_FIELD_NUMBER: _ClassVar[int]
    OBJECT_TOKENS_FIELD_NUMBER: _ClassVar[int]
    LOCAL_TOKENS_FIELD_NUMBER: _ClassVar[int]
    GLOBAL_TOKENS_FIELD_NUMBER: _ClassVar[int]
    ENCODER_VERSION_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    episode_ids: _common_pb2.Tensor
    object_cloud: _common_pb2.Tensor
    environment_cloud: _common_pb2.Tensor
    local_cloud: _common_pb2.Tensor
    object_tokens: _common_pb2.Tensor
    local_tokens: _common_pb2.Tensor
    global_tokens: _common_pb2.Tensor
    encoder_version: int
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., episode_ids: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., object_cloud: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., environment_cloud: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., local_cloud: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., object_tokens: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., local_tokens: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., global_tokens: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., encoder_version: _Optional[int] = ...) -> None: ...

class ObjectPoseEstimate(_message.Message):
    __slots__ = ("header", "pose")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    POSE_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    pose: _common_pb2.Tensor
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., pose: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ...) -> None: ...
