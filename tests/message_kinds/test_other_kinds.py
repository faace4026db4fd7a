"""hamnet.messages: Scene, PerceptionTokens, PolicyAction, Transition, SafeCommand and
Schedule decode what was sent and report each malformed field with the inbox's reason."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from hamnet.messages import (
    action,
    object_pose,
    safe_command,
    safety_event,
    scene,
    schedule,
    tokens,
    transition,
)
from hamnet.proto.common_pb2 import Header
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import CommandMode, SafeCommand, SafetyEventKind
from hamnet.proto.sim_pb2 import Scene
from hamnet.proto.trainer_pb2 import Schedule
from hamnet.runtime.tensor import PayloadError, to_tensor
from tests.scripted import wire

B, K, C, P, J, S = 3, 2, 4, 5, 7, 2


def reason(call) -> str:
    with pytest.raises(PayloadError) as error:
        call()
    return error.value.reason


def scene_message() -> Scene:
    message = Scene(header=Header(step=6, stamp_ns=7), object_ids=["cube", "mug"])
    to_tensor(np.array([2, 0], np.int32), message.env_ids)
    to_tensor(np.array([5, 6], np.int64), message.episode_ids)
    to_tensor(np.ones((K, C, 3), np.float32), message.cuboid_pos)
    to_tensor(np.ones((K, C, 4), np.float32), message.cuboid_quat)
    to_tensor(np.ones((K, C, 3), np.float32), message.cuboid_half_size)
    to_tensor(np.ones((K, C), bool), message.cuboid_active)
    to_tensor(np.ones((K, 25), np.float32), message.env_code)
    to_tensor(np.ones((K, P, 3), np.float32), message.object_points)
    return message


def test_a_scene_decodes_and_checks_its_counts() -> None:
    decoded = scene.decode(wire(scene_message()), ("object_ids",), num_envs=B, num_points=P)
    assert decoded.env_ids.tolist() == [2, 0] and decoded.object_ids == ("cube", "mug")
    assert decoded.cuboid_quat.shape == (K, C, 4) and decoded.start_pose is None
    assert (decoded.step, decoded.stamp_ns) == (6, 7)
    assert reason(lambda: scene.decode(scene_message(), num_envs=2)) == "range"
    assert reason(lambda: scene.decode(scene_message(), num_cuboids=C + 1)) == "shape"
    assert reason(lambda: scene.decode(scene_message(), num_points=P + 1)) == "shape"
    assert reason(lambda: scene.decode(scene_message(), env_code_dim=24)) == "shape"
    assert reason(lambda: scene.decode(scene_message(), ("goal_pose",))) == "missing"
    other = scene_message()
    to_tensor(np.ones((K, C + 1, 4), np.float32), other.cuboid_quat)  # C differs between fields
    assert reason(lambda: scene.decode(other)) == "shape"
    del other.object_ids[1]
    assert reason(lambda: scene.decode(other)) == "shape"


def test_a_scene_description_round_trips() -> None:
    decoded = scene.decode(wire(scene.encode(description(), step=6)))
    sent = description()
    assert decoded.object_ids == sent.object_ids and decoded.env_ids.tolist() == [2, 0]
    np.testing.assert_array_equal(decoded.cuboid_pos, sent.cuboid_centre)
    np.testing.assert_array_equal(decoded.cuboid_half_size, sent.cuboid_half_extent)
    np.testing.assert_array_equal(decoded.object_points, sent.object_points)


def description() -> scene.SceneDescription:
    f = lambda *shape: np.arange(np.prod(shape), dtype=np.float32).reshape(shape)
    return scene.SceneDescription(
        env_ids=np.array([2, 0]), episode_ids=np.array([5, 6]), object_ids=("cube", "mug"),
        object_scale=f(K), object_points=f(K, P, 3), cuboid_centre=f(K, C, 3),
        cuboid_quat=f(K, C, 4), cuboid_half_extent=f(K, C, 3), cuboid_active=np.ones((K, C), bool),
        env_code=f(K, 25), start_pose=f(K, 7), goal_pose=f(K, 7),
    )  # fmt: skip


def tokens_message() -> PerceptionTokens:
    message = PerceptionTokens(header=Header(step=3), encoder_version=2)
    to_tensor(np.arange(B, dtype=np.int64), message.episode_ids)
    for name in tokens.CLOUDS:
        to_tensor(np.zeros((B, P, 3), np.float32), getattr(message, name))
    for name in tokens.TOKENS:
        to_tensor(np.zeros((B, 4, 8), np.float32), getattr(message, name))
    return message


def test_tokens_decode_and_check_batch_and_token_shape() -> None:
    decoded = tokens.decode(wire(tokens_message()), tokens.TOKENS, token_shape=(4, 8))
    assert [t.shape for t in decoded.tokens] == [(B, 4, 8)] * 3
    assert decoded.encoder_version == 2 and decoded.local_cloud.shape == (B, P, 3)
    assert reason(lambda: tokens.decode(tokens_message(), token_shape=(4, 9))) == "shape"
    other = tokens_message()
    to_tensor(np.zeros((B + 1, P, 3), np.float32), other.local_cloud)
    assert reason(lambda: tokens.decode(other)) == "shape"
    other.ClearField("local_cloud")
    assert reason(lambda: tokens.decode(other, tokens.CLOUDS)) == "missing"


def test_an_action_passes_nonfinite_values_and_any_shape() -> None:
    message = PolicyAction(header=Header(step=4, policy_version=9))
    to_tensor(np.full((B, 5), np.nan, np.float32), message.action)
    to_tensor(np.full((B, 3), np.inf, np.float32), message.values)
    decoded = action.decode(wire(message, finite=False), ("action",))
    assert decoded.action.shape == (B, 5) and np.isnan(decoded.action).all()
    assert decoded.policy_version == 9 and decoded.module_weights is None
    assert decoded.episode_ids is None
    assert reason(lambda: action.decode(PolicyAction(), ("action",))) == "missing"
    to_tensor(np.zeros((B, 21), np.float64), message.action)
    assert reason(lambda: action.decode(message)) == "dtype"
    to_tensor(np.zeros(B, np.float32), message.values)
    to_tensor(np.zeros((B, 21), np.float32), message.action)
    assert reason(lambda: action.decode(message)) == "shape"  # values must be (B, R)


def test_a_transition_round_trips_and_checks_its_reward_columns() -> None:
    outcome = SimpleNamespace(
        episode_ids=np.array([4, 5, 6]), reward_terms=np.arange(6.0).reshape(B, 2),
        terminated=np.array([1, 0, 0]), truncated=np.array([0, 1, 0]), success=np.array([1, 0, 0]),
    )  # fmt: skip
    decoded = transition.decode(wire(transition.encode(outcome, ("a", "b"), step=8)))
    assert decoded.step == 8 and decoded.reward_names == ("a", "b")
    np.testing.assert_array_equal(decoded.reward_terms, outcome.reward_terms)
    assert decoded.terminated.tolist() == [True, False, False]
    message = transition.encode(outcome, ("a", "b", "c"), step=8)
    assert reason(lambda: transition.decode(message)) == "shape"
    message = transition.encode(outcome, ("a", "b"), step=8)
    message.ClearField("success")
    assert reason(lambda: transition.decode(message)) == "missing"


def command_message() -> SafeCommand:
    message = SafeCommand(header=Header(step=2), control_dt=0.01)
    to_tensor(np.zeros((B, S, J)), message.q_ref)
    for name in ("kp", "kd", "tau_limit"):
        to_tensor(np.ones((B, J)), getattr(message, name))
    return message


def test_a_safe_command_decodes_into_the_executors_command() -> None:
    step, command = safe_command.decode(wire(command_message()), B, S, 0.01)
    assert step == 2 and command.q_ref.shape == (B, S, J) and command.kp.shape == (B, J)
    assert reason(lambda: safe_command.decode(command_message(), B, S + 1, 0.01)) == "shape"
    assert reason(lambda: safe_command.decode(command_message(), B, S, 0.02)) == "control_dt"
    negative = command_message()
    to_tensor(-np.ones((B, J)), negative.kd)
    assert reason(lambda: safe_command.decode(negative, B, S, 0.01)) == "range"


def test_a_schedule_is_its_counter() -> None:
    assert schedule.decode(wire(Schedule(env_transitions=3 * 2**33))) == 3 * 2**33


def test_an_object_pose_estimate_round_trips_for_one_robot() -> None:
    pose = np.array([0.5, 0.1, 0.2, 1.0, 0.0, 0.0, 0.0])
    step, decoded = object_pose.decode(wire(object_pose.encode(pose, step=12)))
    assert step == 12 and decoded.dtype == np.float32
    np.testing.assert_allclose(decoded, pose)
    two = object_pose.encode(pose, step=12)
    to_tensor(np.zeros((2, 7), np.float32), two.pose)
    assert reason(lambda: object_pose.decode(two)) == "shape"


def test_a_safe_command_carries_its_episode_ids_when_sent() -> None:
    message = command_message()
    assert safe_command.decode(message, B, S, 0.01)[1].episode_ids is None
    to_tensor(np.array([3, 4, 5], np.int64), message.episode_ids)
    assert safe_command.decode(message, B, S, 0.01)[1].episode_ids.tolist() == [3, 4, 5]


def test_the_trainers_schedule_round_trips() -> None:
    message = wire(schedule.encode(5 * 2**31, iteration=3))
    assert schedule.decode(message) == 5 * 2**31 and message.header.step == 3


def test_a_safe_command_round_trips_through_its_one_encoder() -> None:
    b, s, j = 2, 3, 7
    refs = SimpleNamespace(q_ref=np.full((b, s, j), 0.5), dq_ref=np.zeros((b, s, j)),
                           kp=np.full((b, j), 40.0), kd=np.full((b, j), 2.0),
                           tau_limit=np.full((b, j), 10.0))  # fmt: skip
    message = wire(safe_command.encode(refs, 9, CommandMode.HOLD, np.array([4, 5]), 0.0125))
    assert message.mode == CommandMode.HOLD and message.q_ref.dtype == message.kp.dtype
    step, command = safe_command.decode(message, b, s, 0.0125)
    assert step == 9 and np.array_equal(command.episode_ids, [4, 5])
    assert np.array_equal(command.q_ref, refs.q_ref) and np.array_equal(command.kd, refs.kd)


def test_a_safety_event_carries_its_environments_and_stage_figures() -> None:
    figures = SimpleNamespace(stage="joint_limit", commands=10, clipped=3, mean_excess=0.01,
                              max_excess=0.02)  # fmt: skip
    event = wire(safety_event.encode(SafetyEventKind.CLIPPED_JOINT_LIMIT, 4, np.array([1]),
                                     "joint_limit", "clipped", (figures,)))  # fmt: skip
    assert event.header.step == 4 and event.kind == SafetyEventKind.CLIPPED_JOINT_LIMIT
    assert event.stages[0].clipped == 3 and event.env_ids.shape == [1]
