from hamnet.proto import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class CommandMode(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    COMMAND_MODE_UNSPECIFIED: _ClassVar[CommandMode]
    TRACK: _ClassVar[CommandMode]
    HOLD: _ClassVar[CommandMode]
    STOP: _ClassVar[CommandMode]

class SafetyEventKind(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SAFETY_EVENT_KIND_UNSPECIFIED: _ClassVar[SafetyEventKind]
    REJECTED_NONFINITE: _ClassVar[SafetyEventKind]
    REJECTED_SHAPE: _ClassVar[SafetyEventKind]
    CLIPPED_MAGNITUDE: _ClassVar[SafetyEventKind]
    CLIPPED_CARTESIAN: _ClassVar[SafetyEventKind]
    CLIPPED_JOINT_LIMIT: _ClassVar[SafetyEventKind]
    CLIPPED_TORQUE: _ClassVar[SafetyEventKind]
    WATCHDOG_STOP: _ClassVar[SafetyEventKind]
    ESTOP_LATCHED: _ClassVar[SafetyEventKind]
    ESTOP_RESET: _ClassVar[SafetyEventKind]
    REJECTED_EPISODE: _ClassVar[SafetyEventKind]
    ROBOT_ERROR: _ClassVar[SafetyEventKind]
    ROBOT_RESET: _ClassVar[SafetyEventKind]
COMMAND_MODE_UNSPECIFIED: CommandMode
TRACK: CommandMode
HOLD: CommandMode
STOP: CommandMode
SAFETY_EVENT_KIND_UNSPECIFIED: SafetyEventKind
REJECTED_NONFINITE: SafetyEventKind
REJECTED_SHAPE: SafetyEventKind
CLIPPED_MAGNITUDE: SafetyEventKind
CLIPPED_CARTESIAN: SafetyEventKind
CLIPPED_JOINT_LIMIT: SafetyEventKind
CLIPPED_TORQUE: SafetyEventKind
WATCHDOG_STOP: SafetyEventKind
ESTOP_LATCHED: SafetyEventKind
ESTOP_RESET: SafetyEventKind
REJECTED_EPISODE: SafetyEventKind
ROBOT_ERROR: SafetyEventKind
ROBOT_RESET: SafetyEventKind

class SafeCommand(_message.Message):
    __slots__ = ("header", "episode_ids", "mode", "q_ref", "dq_ref", "kp", "kd", "tau_limit", "control_dt")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    EPISODE_IDS_FIELD_NUMBER: _ClassVar[int]
    MODE_FIELD_NUMBER: _ClassVar[int]
    Q_REF_FIELD_NUMBER: _ClassVar[int]
    DQ_REF_FIELD_NUMBER: _ClassVar[int]
    KP_FIELD_NUMBER: _ClassVar[int]
    KD_FIELD_NUMBER: _ClassVar[int]
    TAU_LIMIT_FIELD_NUMBER: _ClassVar[int]
    CONTROL_DT_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    episode_ids: _common_pb2.Tensor
    mode: CommandMode
    q_ref: _common_pb2.Tensor
    dq_ref: _common_pb2.Tensor
    kp: _common_pb2.Tensor
    kd: _common_pb2.Tensor
    tau_limit: _common_pb2.Tensor
    control_dt: float
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., episode_ids: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., mode: _Optional[_Union[CommandMode, str]] = ..., q_ref: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., dq_ref: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., kp: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., kd: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., tau_limit: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., control_dt: _Optional[float] = ...) -> None: ...

class StageStats(_message.Message):
    __slots__ = ("stage", "commands", "clipped", "mean_excess", "max_excess")
    STAGE_FIELD_NUMBER: _ClassVar[int]
    COMMANDS_FIELD_NUMBER: _ClassVar[int]
    CLIPPED_FIELD_NUMBER: _ClassVar[int]
    MEAN_EXCESS_FIELD_NUMBER: _ClassVar[int]
    MAX_EXCESS_FIELD_NUMBER: _ClassVar[int]
    stage: str
    commands: int
    clipped: int
    mean_excess: float
    max_excess: float
    def __init__(self, stage: _Optional[str] = ..., commands: _Optional[int] = ..., clipped: _Optional[int] = ..., mean_excess: _Optional[float] = ..., max_excess: _Optional[float] = ...) -> None: ...

class SafetyEvent(_message.Message):
    __slots__ = ("header", "kind", "env_ids", "stage", "reason", "stages")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    ENV_IDS_FIELD_NUMBER: _ClassVar[int]
    STAGE_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    STAGES_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    kind: SafetyEventKind
    env_ids: _common_pb2.Tensor
    stage: str
    reason: str
    stages: _containers.RepeatedCompositeFieldContainer[StageStats]
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., kind: _Optional[_Union[SafetyEventKind, str]] = ..., env_ids: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., stage: _Optional[str] = ..., reason: _Optional[str] = ..., stages: _Optional[_Iterable[_Union[StageStats, _Mapping]]] = ...) -> None: ...
