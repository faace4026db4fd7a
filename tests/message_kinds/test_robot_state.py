"""hamnet.messages.robot_state: the sim's observation round-trips; every consumer's
`required` fields and every malformed field are reported with the reason the inbox counts."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.messages import robot_state
from hamnet.messages.robot_state import Observation
from hamnet.runtime.tensor import PayloadError, to_tensor
from tests.scripted import wire

B, J, P = 3, 7, 6


def observation(seed: int = 0) -> Observation:
    rng = np.random.default_rng(seed)
    f = lambda *shape: rng.standard_normal(shape).astype(np.float32)
    return Observation(
        episode_ids=np.arange(B, dtype=np.int64) + 10, episode_step=np.array([0, 1, 2], np.int32),
        q=f(B, J), dq=f(B, J), tau=f(B, J), ee_pos_rot6d=f(B, 9), goal_pose=f(B, 7),
        object_pose=f(B, 7), object_velocity=f(B, 6), physics_params=f(B, P),
    )  # fmt: skip


def reason(call) -> str:
    with pytest.raises(PayloadError) as error:
        call()
    return error.value.reason


def test_an_observation_round_trips_with_its_privileged_block() -> None:
    obs = observation()
    message = robot_state.encode_observation(obs, step=4)
    message.header.run, message.header.stamp_ns = 2, 99
    state = robot_state.decode(wire(message), num_envs=B)
    assert (state.run, state.step, state.stamp_ns) == (2, 4, 99)
    for name in ("episode_ids", "episode_step", "q", "dq", "tau", "ee_pos_rot6d", "goal_pose"):
        np.testing.assert_array_equal(getattr(state, name), getattr(obs, name))
    np.testing.assert_array_equal(state.object_pose_estimate, obs.object_pose)
    for name in ("object_pose", "object_velocity", "physics_params"):
        np.testing.assert_array_equal(getattr(state.privileged, name), getattr(obs, name))
    assert state.q.flags.writeable and state.q.dtype == np.float32


def test_fields_left_out_are_none_unless_required() -> None:
    message = robot_state.encode_observation(observation(), step=0)
    for name in ("privileged", "tau", "ee_pos_rot6d", "episode_step"):
        message.ClearField(name)
    state = robot_state.decode(message)
    assert state.privileged is None and state.tau is None and state.episode_step is None
    assert state.q.shape == (B, J)
    assert reason(lambda: robot_state.decode(message, required=("q", "tau"))) == "missing"
    with pytest.raises(ValueError, match="no field"):
        robot_state.decode(message, required=("velocity",))


def test_the_batch_comes_from_num_envs_else_the_episode_ids_else_q() -> None:
    message = robot_state.encode_observation(observation(), step=0)
    assert reason(lambda: robot_state.decode(message, num_envs=B + 1)) == "shape"
    to_tensor(np.zeros(B + 1, np.int64), message.episode_ids)
    assert reason(lambda: robot_state.decode(message)) == "shape"  # q has B rows
    message.ClearField("episode_ids")
    assert len(robot_state.decode(message).q) == B


@pytest.mark.parametrize(
    ("field", "value", "expected"),
    [
        ("q", np.zeros((B, J), np.float64), "dtype"),
        ("q", np.zeros((B, J + 1), np.float32), "shape"),
        ("ee_pos_rot6d", np.zeros((B, 7), np.float32), "shape"),
        ("goal_pose", np.full((B, 7), np.nan, np.float32), "nonfinite"),
        ("episode_ids", np.zeros(B, np.int32), "dtype"),
    ],
)
def test_a_malformed_field_is_dropped_with_its_reason(field, value, expected) -> None:
    message = robot_state.encode_observation(observation(), step=0)
    to_tensor(value, getattr(message, field))
    assert reason(lambda: robot_state.decode(message)) == expected


def test_a_privileged_block_needs_all_three_fields() -> None:
    message = robot_state.encode_observation(observation(), step=0)
    message.privileged.ClearField("physics_params")
    assert reason(lambda: robot_state.decode(message)) == "missing"
    to_tensor(np.zeros((B, 6), np.float32), message.privileged.object_pose)
    assert reason(lambda: robot_state.decode(message)) == "shape"


def test_a_consumer_that_needs_the_privileged_block_says_why_and_may_fix_its_width() -> None:
    """The teacher policy and the sim path of perception both need the privileged block (a
    real robot sends none): the one decoder refuses a state without it, with their reason,
    and checks the physics parameters' width P that a teacher reads."""
    message = robot_state.encode_observation(observation(), step=0)
    state = robot_state.decode(message, privileged_for="a teacher reads it", physics_params=P)
    assert state.privileged.physics_params.shape == (B, P)
    assert reason(lambda: robot_state.decode(message, physics_params=P + 1)) == "shape"
    message.ClearField("privileged")
    assert robot_state.decode(message, physics_params=P).privileged is None  # not needed
    with pytest.raises(PayloadError, match="a teacher reads it") as error:
        robot_state.decode(message, privileged_for="a teacher reads it")
    assert error.value.reason == "missing"
