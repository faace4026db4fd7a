from hamnet.proto import common_pb2 as _common_pb2
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class PolicyAction(_message.Message):
    __slots__ = ("header", "episode_ids", "action", "log_prob", "values", "module_weights", "deterministic", "action_space")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    EPISODE_IDS_FIELD_NUMBER: _ClassVar[int]
    ACTION_FIELD_NUMBER: _ClassVar[int]
    LOG_PROB_FIELD_NUMBER: _ClassVar[int]
    VALUES_FIELD_NUMBER: _ClassVar[int]
    MODULE_WEIGHTS_FIELD_NUMBER: _ClassVar[int]
    DETERMINISTIC_FIELD_NUMBER: _ClassVar[int]
    ACTION_SPACE_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    episode_ids: _common_pb2.Tensor
    action: _common_pb2.Tensor
    log_prob: _common_pb2.Tensor
    values: _common_pb2.Tensor
    module_weights: _common_pb2.Tensor
    deterministic: bool
    action_space: str
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., episode_ids: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., action: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., log_prob: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., values: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., module_weights: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., deterministic: _Optional[bool] = ..., action_space: _Optional[str] = ...) -> None: ...
