"""The sim's shell without a network: every message it encodes round-trips through the wire
format, bad SafeCommands are rejected with the reason the inbox counts them under, and the
lock-step loop, fed a scripted list of messages, publishes what the contract says."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command, hold_command
from hamnet.messages.scene import SceneDescription
from hamnet.proto.common_pb2 import Header
from hamnet.proto.safety_pb2 import SafeCommand
from hamnet.proto.trainer_pb2 import Schedule
from hamnet.runtime.codec import encode
from hamnet.runtime.events import EPISODES_ENDED, EPISODES_SUCCEEDED
from hamnet.runtime.shell_config import ReportConfig
from hamnet.runtime.tensor import PayloadError, from_tensor, to_tensor
from hamnet.sim.config import SimConfig
from hamnet.sim.curriculum import curriculum_values
from hamnet.sim.env import StepResult, VectorEnv
from hamnet.sim.shell import (
    SimLoopConfig,
    SimShell,
    decode_command,
    decode_schedule,
    encode_scene,
    encode_state,
    encode_transition,
)
from hamnet.task.cuboids import NUM_CUBOIDS
from hamnet.task.rewards import REWARD_NAMES
from tests.scripted import ScriptedService, wire

HALFWAY = 1_024_000_000
"""env_transitions halfway through the default curriculum."""

B, S, J = 4, 8, 7
CONTROL_DT = 0.1 / S


def observation(rng: np.random.Generator, b: int = B) -> Observation:
    """Random finite observation of `b` environments with the env's dtypes."""
    f = lambda *shape: rng.standard_normal((b, *shape)).astype(np.float32)
    return Observation(
        episode_ids=rng.integers(0, 1000, b).astype(np.int64),
        episode_step=rng.integers(0, 300, b).astype(np.int32),
        q=f(J), dq=f(J), tau=f(J), ee_pos_rot6d=f(9), goal_pose=f(7),
        object_pose=f(7), object_velocity=f(6), physics_params=f(6),
    )  # fmt: skip


def safe_command(command: Command, step: int, **overrides: np.ndarray) -> SafeCommand:
    """The SafeCommand the safety filter would send for `command` at `step`."""
    arrays = {"q_ref": command.q_ref, "kp": command.kp, "kd": command.kd,
              "tau_limit": command.tau_limit, **overrides}  # fmt: skip
    message = SafeCommand(header=Header(step=step), control_dt=CONTROL_DT)
    for name, array in arrays.items():
        to_tensor(np.asarray(array), getattr(message, name))
    return message


equal, close = np.testing.assert_array_equal, np.testing.assert_allclose


def test_state_round_trips_with_its_privileged_block() -> None:
    obs = observation(np.random.default_rng(0))
    message = wire(encode_state(obs, step=7))
    assert message.header.step == 7
    for name in ("episode_ids", "episode_step", "q", "dq", "tau", "ee_pos_rot6d", "goal_pose"):
        equal(from_tensor(getattr(message, name)), getattr(obs, name))
    for name in ("object_pose", "object_velocity", "physics_params"):
        equal(from_tensor(getattr(message.privileged, name)), getattr(obs, name))
    assert from_tensor(message.episode_ids).dtype == np.int64
    assert from_tensor(message.episode_step).dtype == np.int32


def scene_description(rng: np.random.Generator, k: int) -> SceneDescription:
    """K random scenes with every field filled."""
    c = NUM_CUBOIDS
    f32 = lambda *shape: rng.standard_normal(shape).astype(np.float32)
    return SceneDescription(
        env_ids=np.array([3, 1][:k]), episode_ids=np.array([40, 12][:k]),
        object_ids=("box@0.100", "mug@0.100")[:k], object_scale=f32(k), object_points=f32(k, 512, 3),
        cuboid_centre=f32(k, c, 3), cuboid_quat=f32(k, c, 4), cuboid_half_extent=f32(k, c, 3),
        cuboid_active=rng.random((k, c)) < 0.5, env_code=f32(k, 25), start_pose=f32(k, 7),
        goal_pose=f32(k, 7),
    )  # fmt: skip


def test_scene_message_carries_every_field_of_the_description() -> None:
    scenes = scene_description(np.random.default_rng(1), 2)
    message = wire(encode_scene(scenes, step=5))
    assert message.header.step == 5
    assert list(message.object_ids) == ["box@0.100", "mug@0.100"]
    equal(from_tensor(message.env_ids, np.int32, (2,)), scenes.env_ids)
    equal(from_tensor(message.episode_ids, np.int64, (2,)), scenes.episode_ids)
    fields = {
        "cuboid_pos": "cuboid_centre", "cuboid_quat": "cuboid_quat",
        "cuboid_half_size": "cuboid_half_extent", "env_code": "env_code",
        "object_scale": "object_scale", "start_pose": "start_pose", "goal_pose": "goal_pose",
        "object_points": "object_points",
    }  # fmt: skip
    for name, key in fields.items():
        equal(from_tensor(getattr(message, name), np.float32), getattr(scenes, key))
    equal(from_tensor(message.cuboid_active, bool, (2, NUM_CUBOIDS)), scenes.cuboid_active)


def test_transition_round_trips_with_named_reward_terms() -> None:
    rng = np.random.default_rng(2)
    flags = lambda: rng.random(B) < 0.5
    stepped = observation(rng)
    result = StepResult(
        observation=stepped, final_observation=stepped,
        reward_terms=rng.standard_normal((B, 3)).astype(np.float32),
        terminated=flags(), truncated=flags(), success=flags(), reason=np.zeros(B, np.int8),
        episode_ids=np.arange(B, dtype=np.int64) + 10, reset_ids=np.array([], np.int64),
    )  # fmt: skip
    message = wire(encode_transition(result, REWARD_NAMES, step=3))
    assert message.header.step == 3 and list(message.reward_names) == list(REWARD_NAMES)
    equal(from_tensor(message.reward_terms, np.float32, (B, 3)), result.reward_terms)
    equal(from_tensor(message.episode_ids, np.int64, (B,)), result.episode_ids)
    for name in ("terminated", "truncated", "success"):
        equal(from_tensor(getattr(message, name), bool, (B,)), getattr(result, name))


def test_command_round_trips_in_float32_and_float64() -> None:
    q = np.random.default_rng(3).standard_normal((B, J))
    command = hold_command(q, S)
    for dtype in (np.float64, np.float32):
        cast = {n: getattr(command, n).astype(dtype) for n in ("q_ref", "kp", "kd", "tau_limit")}
        message = wire(safe_command(command, step=11, **cast))
        step, decoded = decode_command(message, B, S, CONTROL_DT)
        assert step == 11
        for name, array in cast.items():
            equal(getattr(decoded, name), array)


def one_env_fewer(c: Command) -> dict[str, np.ndarray]:
    return {n: getattr(c, n)[:-1] for n in ("q_ref", "kp", "kd", "tau_limit")}


BAD_COMMANDS: dict[str, tuple[Callable[[Command], dict], str]] = {
    "batch size": (one_env_fewer, "shape"),
    "sample count": (lambda c: {"q_ref": c.q_ref[:, :-1]}, "shape"),
    "joint count": (lambda c: {"kp": c.kp[:, :6]}, "shape"),
    "integer gains": (lambda c: {"kp": c.kp.astype(np.int64)}, "dtype"),
    "NaN reference": (
        lambda c: {"q_ref": np.where(np.arange(J) == 2, np.nan, c.q_ref)},
        "nonfinite",
    ),
    "negative torque limit": (lambda c: {"tau_limit": -c.tau_limit}, "range"),
}
"""A change to a valid command, and the reason it must be dropped under."""


@pytest.mark.parametrize("case", BAD_COMMANDS, ids=str)
def test_bad_command_is_rejected_with_its_reason(case: str) -> None:
    change, reason = BAD_COMMANDS[case]
    command = hold_command(np.zeros((B, J)), S)
    with pytest.raises(PayloadError) as error:
        decode_command(safe_command(command, 0, **change(command)), B, S, CONTROL_DT)
    assert error.value.reason == reason


def test_command_without_gains_or_at_another_rate_is_rejected() -> None:
    command = hold_command(np.zeros((B, J)), S)
    message = safe_command(command, 0)
    message.ClearField("kd")
    with pytest.raises(PayloadError, match="kd") as error:
        decode_command(message, B, S, CONTROL_DT)
    assert error.value.reason == "missing"
    message = safe_command(command, 0)
    message.control_dt = 0.01
    with pytest.raises(PayloadError) as error:
        decode_command(message, B, S, CONTROL_DT)
    assert error.value.reason == "control_dt"


def test_schedule_carries_the_counter_only() -> None:
    assert decode_schedule(wire(Schedule(env_transitions=5 * 2**30))) == 5 * 2**30


# --- the loop, fed a script instead of a network -----------------------------------------


@pytest.fixture(scope="module")
def env() -> VectorEnv:
    config = SimConfig(num_envs=2, num_objects=2, nthread=1)
    return VectorEnv(replace(config, task=replace(config.task, timeout=3)))


def test_lock_step_loop_steps_on_the_command_of_the_current_step_only(env: VectorEnv) -> None:
    """Each state k is answered by command k. A command for an earlier step, a repeated one
    and a malformed one (counted as a drop) are not executed, and a schedule changes the
    curriculum. Episodes time out after 3 steps, so resets publish their scenes."""
    pending: list[tuple[str, bytes]] = []
    seen: set[int] = set()

    def script(published):
        state = [m for topic, m in published if topic == "state"][-1]
        step = state.header.step
        if step not in seen and step < 6:
            seen.add(step)
            command = hold_command(from_tensor(state.q, np.float32, (2, J)), S)
            answer = encode(safe_command(command, step))
            if step == 0:
                schedule = Schedule(env_transitions=HALFWAY)
                pending.append(("schedule", encode(schedule)))
            if step == 2:
                short = {n: getattr(command, n)[:1] for n in ("q_ref", "kp", "kd", "tau_limit")}
                pending.append(("command", encode(safe_command(command, 0))))  # earlier step
                pending.append(("command", encode(safe_command(command, 2, **short))))  # batch 1
            pending.append(("command", answer))
            if step == 2:
                pending.append(("command", answer))  # repeated: arrives at step 3
        return pending.pop(0) if pending else None

    service = ScriptedService(script)
    shell = SimShell(service, env, SimLoopConfig(report=ReportConfig(report_period_s=1e9)))
    assert shell.run() == 0
    assert [topic for topic, _ in service.published][:2] == ["scene", "state"]
    states = [m for t, m in service.published if t == "state"]
    transitions = [m for t, m in service.published if t == "transition"]
    assert [m.header.step for m in states] == list(range(7))
    assert [m.header.step for m in transitions] == list(range(6))
    for state, transition in zip(states, transitions, strict=False):  # transition k follows state k
        equal(from_tensor(transition.episode_ids), from_tensor(state.episode_ids))
        assert from_tensor(transition.reward_terms, np.float32, (2, 3)).shape == (2, 3)
    truncated = np.array([from_tensor(t.truncated, bool) for t in transitions])  # (T, B)
    assert truncated[2].all() and truncated[5].all()
    # Two timeouts of both environments: the summary's success rate counts 4 episodes.
    assert service.events[EPISODES_ENDED] == 4 and service.events[EPISODES_SUCCEEDED] == 0
    scenes = [m for t, m in service.published if t == "scene"]
    assert [m.header.step for m in scenes] == [0, 3, 6]
    equal(from_tensor(scenes[1].episode_ids), from_tensor(states[3].episode_ids))
    assert set(from_tensor(states[3].episode_ids)).isdisjoint(from_tensor(states[2].episode_ids))
    assert shell.step == 6 and shell.stale == 2
    assert dict(service.drops.counts) == {("hamnet/t/safety/0/command", "shape"): 1}
    assert env.schedule == curriculum_values(HALFWAY, env.config.curriculum)


def test_free_running_loop_holds_the_arm_until_a_command_then_reuses_it(caplog) -> None:
    """At wall-clock rate: without a command the arm holds still (said once in the log); a
    command arriving later is applied whatever its step, and again at every later step."""
    caplog.set_level(logging.INFO, logger="hamnet.sim.shell")
    # Seed 1: both arms start clear of the scene (with seed 0, one starts at the home pose
    # inside a ceiling case and is thrown about by the contacts, held or not).
    env = VectorEnv(SimConfig(num_envs=2, num_objects=2, nthread=1, seed=1))
    sent = []

    def script(published):
        state = [m for topic, m in published if topic == "state"][-1]
        if state.header.step < 2 or sent:
            return None
        reference = from_tensor(state.q, np.float32, (2, J)) + np.array([0.1] + [0.0] * 6)
        sent.append(reference)
        return "command", encode(safe_command(hold_command(reference, S), step=99))

    service = ScriptedService(script, idle=True)
    started = time.monotonic()
    SimShell(service, env, SimLoopConfig(realtime=True, max_steps=6)).run()
    assert time.monotonic() - started >= 0.5  # 6 periods of 0.1 s
    states = [m for t, m in service.published if t == "state"]
    assert [m.header.step for m in states] == list(range(7))
    q = np.array([from_tensor(m.q, np.float32, (2, J)) for m in states])  # (T, B, J)
    assert np.abs(q[2] - q[0]).max() < 0.01  # held
    assert (q[6, :, 0] - q[2, :, 0] > 0.03).all()  # tracking the command's +0.1 rad
    assert sum("no command yet" in r.getMessage() for r in caplog.records) == 1
