"""The monitor's decoders: the focus environment's row out of each batch, and bad input
turned into the PayloadError reason the inbox counts (missing, shape, dtype, env,
decode); a Scene without the focus environment is no frame at all."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.monitor.decode import (
    decode_action,
    decode_event,
    decode_scene,
    decode_state,
    decode_tokens,
    decode_transition,
)
from hamnet.proto.safety_pb2 import SafetyEvent
from hamnet.runtime.tensor import PayloadError, from_tensor, to_tensor
from tests.monitor.recorded import B, action, sim_messages, tokens


@pytest.fixture(scope="module")
def sim() -> dict[str, object]:
    """The first scene, state and transition of a real sim (B = 2)."""
    messages = {}
    for topic, message in sim_messages(1):
        messages.setdefault(topic, message)
    return messages


def reason(call) -> str:
    with pytest.raises(PayloadError) as error:
        call()
    return error.value.reason


def test_state_gives_the_focus_row(sim) -> None:
    state = sim["state"]
    for env in range(B):
        frame = decode_state(state, env)
        np.testing.assert_array_equal(frame.q, from_tensor(state.q)[env])
        np.testing.assert_array_equal(frame.object_pose, from_tensor(state.privileged.object_pose)[env])
        assert frame.episode_id == from_tensor(state.episode_ids)[env]
    assert reason(lambda: decode_state(state, B)) == "env"
    real_robot = type(state)()
    real_robot.CopyFrom(state)
    real_robot.ClearField("privileged")
    assert decode_state(real_robot, 0).object_pose is None
    real_robot.ClearField("goal_pose")
    assert reason(lambda: decode_state(real_robot, 0)) == "missing"
    wrong = type(state)()
    wrong.CopyFrom(state)
    to_tensor(np.zeros((B, 6), np.float32), wrong.q)
    assert reason(lambda: decode_state(wrong, 0)) == "shape"
    to_tensor(np.zeros((B, 7), np.float64), wrong.q)
    assert reason(lambda: decode_state(wrong, 0)) == "dtype"


def test_scene_without_the_focus_environment_is_none(sim) -> None:
    scene = type(sim["scene"])()
    scene.CopyFrom(sim["scene"])
    to_tensor(np.array([1, 0], np.int32), scene.env_ids)  # rows now describe envs 1 and 0
    frame = decode_scene(scene, 0)
    np.testing.assert_array_equal(frame.centre, from_tensor(scene.cuboid_pos)[1])
    assert frame.object_id == scene.object_ids[1]
    assert decode_scene(scene, 5) is None
    del scene.object_ids[1]
    assert reason(lambda: decode_scene(scene, 0)) == "shape"


def test_clouds_actions_and_transitions_check_their_shapes(sim) -> None:
    rng = np.random.default_rng(1)
    message = tokens(0, rng)
    np.testing.assert_array_equal(decode_tokens(message, 1).local, from_tensor(message.local_cloud)[1])
    to_tensor(np.zeros((B + 1, 4, 3), np.float32), message.local_cloud)  # batch differs
    assert reason(lambda: decode_tokens(message, 0)) == "shape"
    policy = action(0, rng)
    assert decode_action(policy, 1).module_weights.shape == (5, 8)
    policy.ClearField("module_weights")
    assert decode_action(policy, 1).module_weights is None  # a baseline without modules
    to_tensor(np.full((B, 3), np.nan, np.float32), policy.values)
    assert np.isnan(decode_action(policy, 0).values).all()  # shown, as the wire allows
    transition = type(sim["transition"])()
    transition.CopyFrom(sim["transition"])
    assert decode_transition(transition, 1, drawn=False).reward_terms.shape == (3,)
    transition.reward_names.append("extra")
    assert reason(lambda: decode_transition(transition, 0, drawn=True)) == "shape"


def test_an_unknown_event_kind_is_a_decode_error() -> None:
    assert reason(lambda: decode_event(SafetyEvent(kind=99))) == "decode"
    assert decode_event(SafetyEvent()).is_statistics
