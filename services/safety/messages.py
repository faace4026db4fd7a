"""The safety service's messages and the supervisor's inputs and outputs: pure decode and
encode functions, tested without a session.

Decodes RobotState (`hamnet.messages.robot_state`, in the filter's float64) and PolicyAction
(`ActionIn`: non-finite values pass, so that the filter's stage 1 rejects them and the
rejection becomes an event); encodes
the supervisor's commands as SafeCommand and its notices as SafetyEvent.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from hamnet.messages import action, robot_state, safe_command
from hamnet.messages.action import ActionIn
from hamnet.messages.robot_state import StateIn
from hamnet.messages.safety_event import encode as encode_event
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import CommandMode, SafeCommand, SafetyEvent, SafetyEventKind
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.tensor import PayloadError
from hamnet.safety.config import ActionSpace
from hamnet.safety.filter import SafeOutput
from hamnet.safety.pipeline import FilterResult
from hamnet.safety.reports import Notice, rejections
from hamnet.safety.stages import Rejection

SAFETY_READS = ("q", "dq", "episode_ids", "episode_step")
"""The RobotState fields the filter reads; a state without one is dropped as `missing`."""


def decode_state(message: RobotState, num_envs: int | None) -> StateIn:
    """RobotState k with q and dq in float64, the filter's precision; `num_envs` None
    accepts any batch size.

    Raises:
        PayloadError: `missing`, `dtype`, `shape` (batch or joint count), `nonfinite`.
    """
    state = robot_state.decode(message, num_envs, required=SAFETY_READS)
    return replace(state, q=state.q.astype(np.float64), dq=state.dq.astype(np.float64))


def decode_action(message: PolicyAction, space: ActionSpace = "joint") -> ActionIn:
    """The step, raw action and episode ids of a PolicyAction for a filter reading actions
    in `space`. NaN, Inf and any shape of the action pass: stage 1 of the core rejects them
    and the rejection becomes an event.

    Raises:
        PayloadError: `missing`, `dtype` (not float32), `shape` (bytes differ from the shape),
            `space` (the policy acts in another action space: executed as this filter reads
            it, its residuals would move the arm elsewhere).
    """
    decoded = action.decode(message, required=("action",))
    if decoded.action_space != space:
        raise PayloadError(
            "space",
            f"the policy acts in the {decoded.action_space!r} action space, this filter "
            f"reads {space!r} (--safety.action-magnitude.space)",
        )
    return decoded


def command_mode(output: SafeOutput) -> CommandMode.ValueType:
    """STOP when every environment is braking or holding (watchdog, e-stop); HOLD when every
    environment's action was rejected (each holds its last safe target); else TRACK. The
    mode sums up the batch: per-environment rejections and stops are in the events."""
    if output.stopping.all():
        return CommandMode.STOP
    if output.filtered is not None and (output.filtered.reason != Rejection.ACCEPTED).all():
        return CommandMode.HOLD
    return CommandMode.TRACK


def encode_command(
    output: SafeOutput, step: int, episode_ids: np.ndarray, control_dt: float
) -> SafeCommand:
    """SafeCommand k of the filter's output, in the mode it sums up to (`command_mode`)."""
    return safe_command.encode(output, step, command_mode(output), episode_ids, control_dt)


def encode_notice(notice: Notice) -> SafetyEvent:
    """The supervisor's notice as its SafetyEvent."""
    kind = SafetyEventKind.Value(notice.kind)
    return encode_event(
        kind, notice.step, notice.env_ids, notice.stage, notice.reason, notice.stats
    )


def rejection_events(filtered: FilterResult, step: int) -> list[SafetyEvent]:
    """One event per rejection reason present in a filter call."""
    return [encode_notice(notice) for notice in rejections(filtered, step)]
