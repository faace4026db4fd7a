from hamnet.proto import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class PrivilegedState(_message.Message):
    __slots__ = ("object_pose", "object_velocity", "physics_params")
    OBJECT_POSE_FIELD_NUMBER: _ClassVar[int]
    OBJECT_VELOCITY_FIELD_NUMBER: _ClassVar[int]
    PHYSICS_PARAMS_FIELD_NUMBER: _ClassVar[int]
    object_pose: _common_pb2.Tensor
    object_velocity: _common_pb2.Tensor
    physics_params: _common_pb2.Tensor
    def __init__(self, object_pose: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., object_velocity: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., physics_params: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ...) -> None: ...

class RobotState(_message.Message):
    __slots__ = ("header", "episode_ids", "episode_step", "q", "dq", "tau", "ee_pos_rot6d", "goal_pose", "privileged", "object_pose_estimate")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    EPISODE_IDS_FIELD_NUMBER: _ClassVar[int]
    EPISODE_STEP_FIELD_NUMBER: _ClassVar[int]
    Q_FIELD_NUMBER: _ClassVar[int]
    DQ_FIELD_NUMBER: _ClassVar[int]
    TAU_FIELD_NUMBER: _ClassVar[int]
    EE_POS_ROT6D_FIELD_NUMBER: _ClassVar[int]
    GOAL_POSE_FIELD_NUMBER: _ClassVar[int]
    PRIVILEGED_FIELD_NUMBER: _ClassVar[int]
    OBJECT_POSE_ESTIMATE_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    episode_ids: _common_pb2.Tensor
    episode_step: _common_pb2.Tensor
    q: _common_pb2.Tensor
    dq: _common_pb2.Tensor
    tau: _common_pb2.Tensor
    ee_pos_rot6d: _common_pb2.Tensor
    goal_pose: _common_pb2.Tensor
    privileged: PrivilegedState
    object_pose_estimate: _common_pb2.Tensor
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., episode_ids: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., episode_step: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., q: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., dq: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., tau: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., ee_pos_rot6d: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., goal_pose: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., privileged: _Optional[_Union[PrivilegedState, _Mapping]] = ..., object_pose_estimate: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ...) -> None: ...

class Scene(_message.Message):
    __slots__ = ("header", "env_ids", "episode_ids", "cuboid_pos", "cuboid_quat", "cuboid_half_size", "cuboid_active", "object_ids", "object_scale", "start_pose", "goal_pose", "env_code", "object_points")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    ENV_IDS_FIELD_NUMBER: _ClassVar[int]
    EPISODE_IDS_FIELD_NUMBER: _ClassVar[int]
    CUBOID_POS_FIELD_NUMBER: _ClassVar[int]
    CUBOID_QUAT_FIELD_NUMBER: _ClassVar[int]
    CUBOID_HALF_SIZE_FIELD_NUMBER: _ClassVar[int]
    CUBOID_ACTIVE_FIELD_NUMBER: _ClassVar[int]
    OBJECT_IDS_FIELD_NUMBER: _ClassVar[int]
    OBJECT_SCALE_FIELD_NUMBER: _ClassVar[int]
    START_POSE_FIELD_NUMBER: _ClassVar[int]
    GOAL_POSE_FIELD_NUMBER: _ClassVar[int]
    ENV_CODE_FIELD_NUMBER: _ClassVar[int]
    OBJECT_POINTS_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    env_ids: _common_pb2.Tensor
    episode_ids: _common_pb2.Tensor
    cuboid_pos: _common_pb2.Tensor
    cuboid_quat: _common_pb2.Tensor
    cuboid_half_size: _common_pb2.Tensor
    cuboid_active: _common_pb2.Tensor
    object_ids: _containers.RepeatedScalarFieldContainer[str]
    object_scale: _common_pb2.Tensor
    start_pose: _common_pb2.Tensor
    goal_pose: _common_pb2.Tensor
    env_code: _common_pb2.Tensor
    object_points: _common_pb2.Tensor
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., env_ids: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., episode_ids: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., cuboid_pos: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., cuboid_quat: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., cuboid_half_size: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., cuboid_active: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., object_ids: _Optional[_Iterable[str]] = ..., object_scale: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., start_pose: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., goal_pose: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., env_code: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., object_points: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ...) -> None: ...

class Transition(_message.Message):
    __slots__ = ("header", "episode_ids", "reward_names", "reward_terms", "terminated", "truncated", "success")
    HEADER_FIELD_NUMBER: _ClassVar[int]
    EPISODE_IDS_FIELD_NUMBER: _ClassVar[int]
    REWARD_NAMES_FIELD_NUMBER: _ClassVar[int]
    REWARD_TERMS_FIELD_NUMBER: _ClassVar[int]
    TERMINATED_FIELD_NUMBER: _ClassVar[int]
    TRUNCATED_FIELD_NUMBER: _ClassVar[int]
    SUCCESS_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    episode_ids: _common_pb2.Tensor
    reward_names: _containers.RepeatedScalarFieldContainer[str]
    reward_terms: _common_pb2.Tensor
    terminated: _common_pb2.Tensor
    truncated: _common_pb2.Tensor
    success: _common_pb2.Tensor
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., episode_ids: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., reward_names: _Optional[_Iterable[str]] = ..., reward_terms: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., terminated: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., truncated: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ..., success: _Optional[_Union[_common_pb2.Tensor, _Mapping]] = ...) -> None: ...
