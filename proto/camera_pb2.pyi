from hamnet.proto import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class CameraFrame(_message.Message):
    __slots__ = ("name", "depth", "intrinsics", "camera_to_world", "labels")
    NAME_FIELD_NUMBER: _ClassVar[int]
    DEPTH_FIELD_NUMBER: _ClassVar[int]
    INTRINSICS_FIELD_NUMBER: _ClassVar[int]
    CAMERA_TO_WORLD_FIELD_NUMBER: _ClassVar[int]
    LABELS_FIELD_NUMBER: _ClassVar[int]
    name: str
    depth: _common_pb2.Tensor
    intrinsics: _common_pb2.Tensor
    camera_to_world: _common_pb2.Tensor
    labels: _common_pb2.Tensor
    def __init__(self, name: _Optional[str] = ..., depth: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., intrinsics: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., camera_to_world: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., labels: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ...) -> None: ...

class DepthFrames(_message.Message):
    __slots__ = ("header", "cameras")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    CAMERAS_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    cameras: _containers.RepeatedCompositeFieldContainer[CameraFrame]
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., cameras: _Optional[_Iterable[_Union[CameraFrame, _Mapping]]] = ...) -> None: ...
