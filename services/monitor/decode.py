"""Protobuf messages -> the frames the view draws (`hamnet.monitor.frames`): the
environment in focus cut out of each batch, every tensor checked (dtype, shape, batch
size) on the way. Pure functions, tested without a session; a bad message raises
`PayloadError`, which the inbox counts under (key, reason) and drops.

Reasons beyond the runtime's: `env` (the environment in focus is not in the batch). Scenes
must have the sim's C = 16 cuboid slots: the view colours and names them by slot.
"""

from __future__ import annotations

import numpy as np

from hamnet.messages import action, robot_state, scene, tokens, transition
from hamnet.monitor.frames import (
    ActionFrame,
    CloudsFrame,
    EventFrame,
    MetricsFrame,
    SceneFrame,
    StageFigures,
    StateFrame,
    TransitionFrame,
)
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafetyEvent, SafetyEventKind
from hamnet.proto.sim_pb2 import RobotState, Scene, Transition
from hamnet.proto.trainer_pb2 import Metrics
from hamnet.runtime.tensor import PayloadError, field_array
from hamnet.task.cuboids import NUM_CUBOIDS


def focus_row(array: np.ndarray, env: int) -> np.ndarray:
    """Row `env` of a batched (B, ...) array.

    Raises:
        PayloadError: `env` when the batch has no row `env`.
    """
    if env >= len(array):
        raise PayloadError("env", f"environment {env} is not in a batch of {len(array)} (--env)")
    return array[env]


def decode_state(message: RobotState, env: int) -> StateFrame:
    """StateFrame of environment `env` from a RobotState of B environments."""
    state = robot_state.decode(message, required=("q", "goal_pose", "episode_ids"))
    object_pose = None
    if state.privileged is not None:
        object_pose = focus_row(state.privileged.object_pose, env)
    return StateFrame(
        step=state.step,
        stamp_ns=state.stamp_ns,
        episode_id=int(focus_row(state.episode_ids, env)),
        q=focus_row(state.q, env),
        goal_pose=focus_row(state.goal_pose, env),
        object_pose=object_pose,
    )


_SCENE_READS = (
    "episode_ids",
    "object_ids",
    "object_points",
    "start_pose",
    "goal_pose",
    "cuboid_pos",
    "cuboid_quat",
    "cuboid_half_size",
    "cuboid_active",
)


def decode_scene(message: Scene, env: int) -> SceneFrame | None:
    """SceneFrame of environment `env`, or None when the Scene does not describe it."""
    decoded = scene.decode(message, _SCENE_READS, num_cuboids=NUM_CUBOIDS)
    rows = np.flatnonzero(decoded.env_ids == env)
    if not len(rows):
        return None
    row = int(rows[0])
    return SceneFrame(
        step=decoded.step,
        stamp_ns=decoded.stamp_ns,
        episode_id=int(decoded.episode_ids[row]),
        object_id=decoded.object_ids[row],
        centre=decoded.cuboid_pos[row],
        quat=decoded.cuboid_quat[row],
        half_extent=decoded.cuboid_half_size[row],
        active=decoded.cuboid_active[row],
        object_points=decoded.object_points[row],
        start_pose=decoded.start_pose[row],
        goal_pose=decoded.goal_pose[row],
    )


def decode_tokens(message: PerceptionTokens, env: int) -> CloudsFrame:
    """CloudsFrame of environment `env` (the three clouds; the tokens are not drawn)."""
    decoded = tokens.decode(message, required=tokens.CLOUDS)
    return CloudsFrame(
        step=decoded.step,
        stamp_ns=decoded.stamp_ns,
        object=focus_row(decoded.object_cloud, env),
        environment=focus_row(decoded.environment_cloud, env),
        local=focus_row(decoded.local_cloud, env),
    )


def decode_action(message: PolicyAction, env: int) -> ActionFrame:
    """ActionFrame of environment `env`. Non-finite values pass, as on the wire (the
    safety service rejects them; the view shows them)."""
    decoded = action.decode(message)
    weights, values = decoded.module_weights, decoded.values
    return ActionFrame(
        step=decoded.step,
        stamp_ns=decoded.stamp_ns,
        policy_version=decoded.policy_version,
        module_weights=None if weights is None else focus_row(weights, env),
        values=None if values is None else focus_row(values, env),
    )


def decode_transition(message: Transition, env: int, drawn: bool) -> TransitionFrame:
    """TransitionFrame: `env`'s reward terms and every environment's episode ends."""
    decoded = transition.decode(message)
    return TransitionFrame(
        step=decoded.step,
        stamp_ns=decoded.stamp_ns,
        drawn=drawn,
        reward_names=decoded.reward_names,
        reward_terms=focus_row(decoded.reward_terms, env),
        done=decoded.terminated | decoded.truncated,
        success=decoded.success,
    )


def decode_event(message: SafetyEvent) -> EventFrame:
    """EventFrame of a SafetyEvent (every environment: the text says whether the focus
    environment is concerned)."""
    try:
        kind = SafetyEventKind.Name(message.kind)
    except ValueError:
        raise PayloadError("decode", f"SafetyEvent.kind {message.kind} is unknown") from None
    env_ids = np.zeros(0, dtype=np.int32)
    if message.HasField("env_ids"):
        env_ids = field_array(message, "env_ids", np.int32, (None,))
    stages = tuple(
        StageFigures(s.stage, s.commands, s.clipped, s.mean_excess, s.max_excess)
        for s in message.stages
    )
    return EventFrame(
        step=message.header.step,
        stamp_ns=message.header.stamp_ns,
        kind=kind,
        stage=message.stage,
        reason=message.reason,
        env_ids=env_ids,
        stages=stages,
    )


def decode_metrics(message: Metrics) -> MetricsFrame:
    """MetricsFrame of one trainer update."""
    return MetricsFrame(
        step=message.header.step,
        stamp_ns=message.header.stamp_ns,
        iteration=message.iteration,
        scalars=dict(message.scalars),
    )
