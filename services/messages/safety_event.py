"""SafetyEvent (safety, bridge -> monitor, launcher): what a stage clipped, rejected or
stopped, and the robot's errors and resets; one encoder for both publishers.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from hamnet.proto.common_pb2 import Header
from hamnet.proto.safety_pb2 import SafetyEvent, SafetyEventKind
from hamnet.proto.safety_pb2 import StageStats as StageStatsMessage
from hamnet.runtime.tensor import to_tensor


class StageFigures(Protocol):
    """One stage's statistics over a period (`hamnet.safety.stats.StageStats`)."""

    stage: str
    commands: int
    clipped: int
    mean_excess: float
    max_excess: float


def encode(
    kind: SafetyEventKind.ValueType,
    step: int,
    env_ids: np.ndarray | None = None,
    stage: str = "",
    reason: str = "",
    stats: Sequence[StageFigures] = (),
) -> SafetyEvent:
    """One SafetyEvent at state step `step`, about environments `env_ids` (K,)."""
    message = SafetyEvent(header=Header(step=step), kind=kind, stage=stage, reason=reason)
    if env_ids is not None:
        to_tensor(np.asarray(env_ids, dtype=np.int32), message.env_ids)  # (K,)
    message.stages.extend(
        StageStatsMessage(
            stage=s.stage,
            commands=s.commands,
            clipped=s.clipped,
            mean_excess=s.mean_excess,
            max_excess=s.max_excess,
        )
        for s in stats
    )
    return message
