"""Small known recordings for the recorder's tests: real protobuf messages of the contract,
numbered so that any loss, duplicate or reordering shows."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hamnet.proto.sim_pb2 import RobotState, Transition
from hamnet.recorder.config import RecorderConfig
from hamnet.recorder.writer import RecordingWriter
from hamnet.runtime.tensor import to_tensor

NS = "rec"
STATE = f"hamnet/{NS}/sim/0/state"
TRANSITION = f"hamnet/{NS}/sim/0/transition"
RAW = f"hamnet/{NS}/custom/raw"
"""A key outside the contract: recorded on a raw channel."""
T0 = 1_700_000_000_000_000_000
"""Log time of the first message, Unix ns."""


def state(step: int, stamp_ns: int) -> bytes:
    """A robot state of 2 environments for `step`, its joint positions numbered by step."""
    message = RobotState()
    message.header.source, message.header.step, message.header.stamp_ns = "sim/0", step, stamp_ns
    message.q.CopyFrom(to_tensor(np.full((2, 7), step, np.float32)))
    return message.SerializeToString()


def transition(step: int, stamp_ns: int) -> bytes:
    message = Transition()
    message.header.source, message.header.step, message.header.stamp_ns = "sim/0", step, stamp_ns
    return message.SerializeToString()


def lock_step(steps: int, period_ns: int = 100_000_000) -> list[tuple[str, bytes, int]]:
    """(key, payload, log time) of `steps` policy steps of a lock-step sim: state k, a raw
    message, transition k; state 0 is sent twice (the sim's resend while it waits)."""
    messages = []
    for k in range(steps):
        t = T0 + k * period_ns
        messages.append((STATE, state(k, t - 1000), t))
        if k == 0:
            messages.append((STATE, state(0, t + 10), t + 10))
        messages.append((RAW, f"raw {k}".encode(), t + 20))
        messages.append((TRANSITION, transition(k, t + 30), t + 40))
    return messages


def write(path: Path, messages: list[tuple[str, bytes, int]], **config) -> RecordingWriter:
    """Record `messages` (publish time = log time - 7 ns) to `path`; returns the closed writer."""
    writer = RecordingWriter(RecorderConfig(output=path, **config), {"namespace": NS}, T0)
    for key, payload, log_time in messages:
        writer.write(key, payload, log_time, log_time - 7)
        writer.poll(log_time)
    writer.close()
    return writer
