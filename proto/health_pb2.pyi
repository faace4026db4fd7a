from hamnet.proto import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class ServiceState(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SERVICE_STATE_UNSPECIFIED: _ClassVar[ServiceState]
    STARTING: _ClassVar[ServiceState]
    RUNNING: _ClassVar[ServiceState]
    STOPPING: _ClassVar[ServiceState]
SERVICE_STATE_UNSPECIFIED: ServiceState
STARTING: ServiceState
RUNNING: ServiceState
STOPPING: ServiceState

class DropCount(_message.Message):
    __slots__ = ("key", "reason", "count")
    KEY_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    COUNT_FIELD_NUMBER: _ClassVar[int]
    key: str
    reason: str
    count: int
    def __init__(self, key: _Optional[str] = ..., reason: _Optional[str] = ..., count: _Optional[int] = ...) -> None: ...

class Health(_message.Message):
    __slots__ = ("header", "service", "worker", "state", "uptime_s", "received", "published", "drops", "loop_rate_hz", "events", "figures")
    class ReceivedEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class PublishedEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class EventsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class FiguresEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: float
        def __init__(self, key: _Optional[str] = ..., value: _Optional[float] = ...) -> None: ...
    HEADER_FIELD_NUMBER: _ClassVar[int]
    SERVICE_FIELD_NUMBER: _ClassVar[int]
    WORKER_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    UPTIME_S_FIELD_NUMBER: _ClassVar[int]
    RECEIVED_FIELD_NUMBER: _ClassVar[int]
    PUBLISHED_FIELD_NUMBER: _ClassVar[int]
    DROPS_FIELD_NUMBER: _ClassVar[int]
    LOOP_RATE_HZ_FIELD_NUMBER: _ClassVar[int]
    EVENTS_FIELD_NUMBER: _ClassVar[int]
    FIGURES_FIELD_NUMBER: _ClassVar[int]
    header: _common_pb2.Header
    service: str
    worker: str
    state: ServiceState
    uptime_s: float
    received: _containers.ScalarMap[str, int]
    published: _containers.ScalarMap[str, int]
    drops: _containers.RepeatedCompositeFieldContainer[DropCount]
    loop_rate_hz: float
    events: _containers.ScalarMap[str, int]
    figures: _containers.ScalarMap[str, float]
    def __init__(self, header: _Optional[_Union[_common_pb2.Header, _Mapping]] = ..., service: _Optional[str] = ..., worker: _Optional[str] = ..., state: _Optional[_Union[ServiceState, str]] = ..., uptime_s: _Optional[float] = ..., received: _Optional[_Mapping[str, int]] = ..., published: _Optional[_Mapping[str, int]] = ..., drops: _Optional[_Iterable[_Union[DropCount, _Mapping]]] = ..., loop_rate_hz: _Optional[float] = ..., events: _Optional[_Mapping[str, int]] = ..., figures: _Optional[_Mapping[str, float]] = ...) -> None: ...
