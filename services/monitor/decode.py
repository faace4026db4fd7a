"""Protobuf messages -> the frames the view draws (`hamnet.monitor.frames`): the
environment in focus cut out of each batch, every tensor checked (dtype, shape, batch
size) on the way. Pure functions, tested without a session; a bad message raises
`PayloadError`, which the inbox counts under (key, reason) and drops.

Reasons beyond the runtime's: `env` (the environment in focus is not in the batch). Scenes
must have the sim's C = 16 cuboid slots: the view colours and names them by slot.
"""

from __future__ import annotations

import numpy as np

from hamnet.fr3.limits import NUM_JOINTS as J
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
from hamnet.sim.scene import NUM_CUBOIDS


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
    q = field_array(message, "q", np.float32, (None, J))  # (B, J)
    b = len(q)
    goal = field_array(message, "goal_pose", np.float32, (b, 7))
    ids = field_array(message, "episode_ids", np.int64, (b,))
    object_pose = None
    if message.HasField("privileged") and message.privileged.HasField("object_pose"):
        object_pose = focus_row(field_array(message.privileged, "object_pose", np.float32, (b, 7)), env)
    return StateFrame(
        step=message.header.step,
        stamp_ns=message.header.stamp_ns,
        episode_id=int(focus_row(ids, env)),
        q=focus_row(q, env),
        goal_pose=focus_row(goal, env),
        object_pose=object_pose,
    )


def decode_scene(message: Scene, env: int) -> SceneFrame | None:
    """SceneFrame of environment `env`, or None when the Scene does not describe it."""
    env_ids = field_array(message, "env_ids", np.int32, (None,))  # (K,)
    k = len(env_ids)
    arrays = {
        "centre": field_array(message, "cuboid_pos", np.float32, (k, NUM_CUBOIDS, 3)),  # (K, C, 3)
        "quat": field_array(message, "cuboid_quat", np.float32, (k, NUM_CUBOIDS, 4)),
        "half_extent": field_array(message, "cuboid_half_size", np.float32, (k, NUM_CUBOIDS, 3)),
        "active": field_array(message, "cuboid_active", np.bool_, (k, NUM_CUBOIDS)),
        "object_points": field_array(message, "object_points", np.float32, (k, None, 3)),  # (K, P, 3)
        "start_pose": field_array(message, "start_pose", np.float32, (k, 7)),
        "goal_pose": field_array(message, "goal_pose", np.float32, (k, 7)),
    }
    ids = field_array(message, "episode_ids", np.int64, (k,))
    if len(message.object_ids) != k:
        raise PayloadError("shape", f"Scene.object_ids: {len(message.object_ids)} names for {k} envs")
    rows = np.flatnonzero(env_ids == env)
    if not len(rows):
        return None
    row = int(rows[0])
    return SceneFrame(
        step=message.header.step,
        stamp_ns=message.header.stamp_ns,
        episode_id=int(ids[row]),
        object_id=message.object_ids[row],
        **{name: array[row] for name, array in arrays.items()},
    )


def decode_tokens(message: PerceptionTokens, env: int) -> CloudsFrame:
    """CloudsFrame of environment `env` (the three clouds; the tokens are not drawn)."""
    clouds = {}
    b = None
    for name in ("object", "environment", "local"):
        cloud = field_array(message, f"{name}_cloud", np.float32, (b, None, 3))  # (B, P, 3)
        b = len(cloud)
        clouds[name] = focus_row(cloud, env)
    return CloudsFrame(step=message.header.step, stamp_ns=message.header.stamp_ns, **clouds)


def decode_action(message: PolicyAction, env: int) -> ActionFrame:
    """ActionFrame of environment `env`. Non-finite values pass, as on the wire (the
    safety service rejects them; the view shows them)."""
    weights = values = None
    if message.HasField("module_weights"):
        weights = focus_row(field_array(message, "module_weights", np.float32, (None, None, None),
                                   finite=False), env)  # fmt: skip
    if message.HasField("values"):
        values = focus_row(field_array(message, "values", np.float32, (None, None), finite=False), env)
    return ActionFrame(
        step=message.header.step,
        stamp_ns=message.header.stamp_ns,
        policy_version=message.header.policy_version,
        module_weights=weights,
        values=values,
    )


def decode_transition(message: Transition, env: int, drawn: bool) -> TransitionFrame:
    """TransitionFrame: `env`'s reward terms and every environment's episode ends."""
    names = tuple(message.reward_names)
    terms = field_array(message, "reward_terms", np.float32, (None, len(names)))  # (B, R)
    b = len(terms)
    terminated, truncated, success = (
        field_array(message, name, np.bool_, (b,)) for name in ("terminated", "truncated", "success")
    )
    return TransitionFrame(
        step=message.header.step,
        stamp_ns=message.header.stamp_ns,
        drawn=drawn,
        reward_names=names,
        reward_terms=focus_row(terms, env),
        done=terminated | truncated,
        success=success,
    )


def decode_event(message: SafetyEvent) -> EventFrame:
    """EventFrame of a SafetyEvent (every environment: the text says whether the focus
    environment is concerned)."""
    try:
        kind = SafetyEventKind.Name(message.kind)
    except ValueError:
        raise PayloadError("decode", f"SafetyEvent.kind {message.kind} is unknown") from None
    env_ids = field_array(message, "env_ids", np.int32, (None,)) if message.HasField("env_ids") else (
        np.zeros(0, dtype=np.int32))  # fmt: skip
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
