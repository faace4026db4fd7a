"""The safety shell without a network: its messages round-trip through the wire format (its
commands through the sim's own decoder), bad input becomes the PayloadError the inbox
counts, a non-finite action reaches the core and becomes a REJECTED_NONFINITE event, and
the loop, fed a scripted list of states and actions, answers each state k with command k,
brakes on the watchdog, resumes when actions return, and obeys the e-stop latch."""

from __future__ import annotations

import json
import time
from collections.abc import Callable

import numpy as np
import pytest

from hamnet.fr3.limits import Q_HOME
from hamnet.messages.safe_command import decode as decode_command
from hamnet.messages.safety_event import encode as encode_event
from hamnet.messages.schedule import decode as decode_schedule
from hamnet.proto.common_pb2 import Header
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import CommandMode, SafetyEvent, SafetyEventKind
from hamnet.proto.sim_pb2 import RobotState
from hamnet.proto.trainer_pb2 import Schedule
from hamnet.runtime.codec import encode, parse
from hamnet.runtime.service import ServiceIdentity
from hamnet.runtime.tensor import PayloadError, from_tensor, to_tensor
from hamnet.safety.estop import EStop
from hamnet.safety.filter import SafetyFilter
from hamnet.safety.messages import decode_action, decode_state, encode_command, rejection_events
from hamnet.safety.shell import SafetyShell
from hamnet.safety.stats import StageStats
from hamnet.safety.supervisor import SafetyLoopConfig, episode_starts
from tests.scripted import ScriptedService, wire

B, S, J = 2, 8, 7
CONTROL_DT = 0.1 / S


def robot_state(
    step: int, q: np.ndarray | None = None, episode_step: int | None = None, run: int = 0
):
    """RobotState `step` of the sim's `run`, B environments at q (default: home, at rest)."""
    q = np.tile(Q_HOME, (B, 1)) if q is None else q
    message = RobotState(header=Header(step=step, run=run))
    to_tensor(q.astype(np.float32), message.q)  # (B, J)
    to_tensor(np.zeros((B, J), np.float32), message.dq)  # (B, J)
    to_tensor(np.arange(B, dtype=np.int64), message.episode_ids)  # (B,)
    to_tensor(np.full(B, step if episode_step is None else episode_step, np.int32),
              message.episode_step)  # fmt: skip
    return message


def policy_action(step: int, action: np.ndarray) -> PolicyAction:
    message = PolicyAction(header=Header(step=step))
    to_tensor(np.asarray(action, np.float32), message.action)  # (B, 21)
    return message


# --- decode / encode ---------------------------------------------------------------------


def test_state_decodes_to_float64_arrays_and_checks_the_batch() -> None:
    q = np.tile(Q_HOME, (B, 1)) + 0.01
    state = decode_state(wire(robot_state(3, q, episode_step=0)), num_envs=B)
    assert state.step == 3 and state.q.dtype == np.float64 and state.q.shape == (B, J)
    np.testing.assert_allclose(state.q, q, atol=1e-6)
    assert state.episode_step.tolist() == [0, 0] and state.episode_ids.tolist() == [0, 1]
    assert decode_state(robot_state(0), num_envs=None).q.shape == (B, J)
    with pytest.raises(PayloadError) as error:
        decode_state(robot_state(0), num_envs=3)
    assert error.value.reason == "shape"
    missing = robot_state(0)
    missing.ClearField("dq")
    with pytest.raises(PayloadError) as error:
        decode_state(missing, num_envs=B)
    assert error.value.reason == "missing"
    nan = robot_state(0, np.full((B, J), np.nan))
    with pytest.raises(PayloadError) as error:
        decode_state(nan, num_envs=B)
    assert error.value.reason == "nonfinite"


def test_nonfinite_action_passes_the_transport_and_the_decoder() -> None:
    """The contract lets NaN through on policy/action: a decoder that checked finiteness
    would drop it as a transport error, and no REJECTED_NONFINITE event would ever be sent."""
    action = np.zeros((B, 21), np.float32)
    action[1, 4] = np.nan
    message = parse(PolicyAction, encode(policy_action(5, action)))
    decoded = decode_action(message)
    assert decoded.step == 5 and decoded.action.shape == (B, 21)
    assert np.isnan(decoded.action[1, 4]) and decoded.episode_ids is None
    with pytest.raises(PayloadError) as error:
        decode_action(PolicyAction())
    assert error.value.reason == "missing"
    double = PolicyAction()
    to_tensor(np.zeros((B, 21)), double.action)  # float64: not the contract's dtype
    with pytest.raises(PayloadError) as error:
        decode_action(double)
    assert error.value.reason == "dtype"


def test_nonfinite_action_becomes_a_rejection_event() -> None:
    """The decoded NaN action reaches the core: env 1 is rejected, env 0 follows its action,
    and the event names env 1 only."""
    safety = SafetyFilter(np.tile(Q_HOME, (B, 1)))
    action = np.zeros((B, 21), np.float32)
    action[1, 0] = np.inf
    decoded = decode_action(parse(PolicyAction, encode(policy_action(0, action)))).action
    output = safety.command(decoded, np.tile(Q_HOME, (B, 1)), np.zeros((B, J)), step=0)
    assert np.isfinite(output.q_ref).all()
    events = [wire(e) for e in rejection_events(output.filtered, step=4)]
    assert len(events) == 1
    assert events[0].kind == SafetyEventKind.REJECTED_NONFINITE
    assert events[0].header.step == 4 and events[0].stage == "nonfinite_guard"
    assert from_tensor(events[0].env_ids).tolist() == [1]


def test_action_for_an_ended_episode_is_held_and_reported() -> None:
    """Env 1 was reset after the policy saw its state: its residual, meant for the old
    scene, must not move the arm (held at the measured q), and a REJECTED_EPISODE event
    names env 1 only; env 0, same episode, follows its action."""
    q = np.tile(Q_HOME, (B, 1))
    state = decode_state(wire(robot_state(7, q)), num_envs=B)  # episode ids [0, 1]
    message = policy_action(7, np.full((B, 21), 0.5, np.float32))
    to_tensor(np.array([0, 99], np.int64), message.episode_ids)  # (B,) env 1: old episode
    decoded = decode_action(wire(message))
    assert decoded.stale(state).tolist() == [False, True]
    safety = SafetyFilter(q)
    output = safety.command(decoded.action, q, np.zeros((B, J)), step=0, stale=decoded.stale(state))
    assert output.filtered.reason.tolist() == [0, 4]
    np.testing.assert_allclose(output.filtered.q_target[1], q[1])
    assert np.abs(output.filtered.q_target[0] - q[0]).max() > 1e-3
    events = [wire(e) for e in rejection_events(output.filtered, step=7)]
    assert [e.kind for e in events] == [SafetyEventKind.REJECTED_EPISODE]
    assert from_tensor(events[0].env_ids).tolist() == [1]
    wrong_batch = policy_action(7, np.zeros((B, 21), np.float32))
    to_tensor(np.arange(3, dtype=np.int64), wrong_batch.episode_ids)  # (3,): not the batch
    assert decode_action(wire(wrong_batch)).stale(state) is None


def test_command_round_trips_through_the_sims_decoder() -> None:
    safety = SafetyFilter(np.tile(Q_HOME, (B, 1)))
    output = safety.command(np.zeros((B, 21)), np.tile(Q_HOME, (B, 1)), np.zeros((B, J)), 0)
    message = wire(encode_command(output, 7, np.array([3, 4]), CONTROL_DT))
    assert message.mode == CommandMode.TRACK and message.control_dt == CONTROL_DT
    assert from_tensor(message.episode_ids).tolist() == [3, 4]
    np.testing.assert_array_equal(from_tensor(message.dq_ref), output.dq_ref)
    step, command = decode_command(message, B, S, CONTROL_DT)
    assert step == 7
    np.testing.assert_array_equal(command.q_ref, output.q_ref)
    for name in ("kp", "kd", "tau_limit"):
        np.testing.assert_array_equal(getattr(command, name), getattr(output, name))
    safety.stop(np.arange(B))
    braking = wire(encode_command(safety.brake(output.q_ref[:, -1], np.zeros((B, J))), 8,
                                  np.array([3, 4]), CONTROL_DT))  # fmt: skip
    assert braking.mode == CommandMode.STOP


def test_mode_is_hold_only_when_every_action_was_rejected() -> None:
    """One NaN row: the batch still tracks (the event names the row); NaN everywhere: every
    environment holds its last safe target, and the command says HOLD."""
    q = np.tile(Q_HOME, (B, 1))
    safety = SafetyFilter(q)
    action = np.zeros((B, 21))
    action[0, 3] = np.nan
    one = safety.command(action, q, np.zeros((B, J)), 0)
    assert wire(encode_command(one, 1, np.arange(B), CONTROL_DT)).mode == CommandMode.TRACK
    every = safety.command(np.full((B, 21), np.nan), q, np.zeros((B, J)), 0)
    assert wire(encode_command(every, 2, np.arange(B), CONTROL_DT)).mode == CommandMode.HOLD
    np.testing.assert_allclose(every.q_ref[:, -1], q, atol=1e-9)


def test_event_and_schedule_round_trip() -> None:
    stats = (StageStats("joint_limits", 10, 2, 0.5, 0.75),)
    event = wire(encode_event(SafetyEventKind.CLIPPED_JOINT_LIMIT, 9, np.array([0, 1]),
                              "joint_limits", "why", stats))  # fmt: skip
    assert event.kind == SafetyEventKind.CLIPPED_JOINT_LIMIT and event.reason == "why"
    assert from_tensor(event.env_ids).dtype == np.int32
    assert [(s.stage, s.commands, s.clipped, s.mean_excess, s.max_excess)
            for s in event.stages] == [("joint_limits", 10, 2, 0.5, 0.75)]  # fmt: skip
    assert decode_schedule(wire(Schedule(env_transitions=123456))) == 123456


def test_episode_starts_at_step_zero_or_a_new_episode_id() -> None:
    state = decode_state(robot_state(5, episode_step=3), B)
    assert episode_starts(state, np.array([0, 1])).tolist() == []
    assert episode_starts(state, np.array([0, 9])).tolist() == [1]
    assert episode_starts(decode_state(robot_state(5, episode_step=0), B), None).tolist() == [0, 1]


def test_estop_latch_answers_in_json_and_queues_requests() -> None:
    estop = EStop()
    ok, answer = estop.request("status")
    assert ok and json.loads(answer) == {"latched": False}
    assert estop.request(" STOP\n")[0] and estop.latched
    assert json.loads(estop.request("reset")[1])["latched"] is False
    assert estop.take() == ["stop", "reset"] and estop.take() == []
    ok, answer = estop.request("halt")
    assert not ok and "unknown" in answer


# --- the loop, fed a script instead of a network -------------------------------------------


def scripted(script) -> ScriptedService:
    """The safety service on a scripted network that stays quiet when the script has nothing."""
    return ScriptedService(script, ServiceIdentity("safety", "0"), idle=True)


def of(published, topic: str) -> list:
    return [m for t, m in published if t == topic]


def sim_script(act: Callable[[int], np.ndarray | None], last: int, hooks=None):
    """A lock-step sim: state k+1 follows command k; `act(k)` is the policy's action for
    state k (None: the policy is silent); `hooks[k]()` runs when state k is sent."""
    queue: list = []
    sent: set[int] = set()
    hooks = hooks or {}

    def script(published):
        commands = of(published, "command")
        step = commands[-1].header.step + 1 if commands else 0
        if step > last:
            return "end"
        if step not in sent:
            sent.add(step)
            if step in hooks:
                queue.extend(hooks[step]() or [])
            queue.append(("state", encode(robot_state(step))))
            action = act(step)
            if action is not None:
                queue.append(("action", encode(policy_action(step, action))))
        return queue.pop(0) if queue else None

    return script


def test_loop_answers_each_state_and_rejects_a_nan_action() -> None:
    """States 0-5 with actions; the action of state 2 holds a NaN in env 0, one malformed
    action payload is counted as a drop, a schedule sets the global step."""
    rng = np.random.default_rng(0)

    def act(step: int) -> np.ndarray:
        action = 0.1 * rng.standard_normal((B, 21)).astype(np.float32)
        if step == 2:
            action[0, 3] = np.nan
        return action

    hooks = {1: lambda: [("action", b"\xff not a message"),
                         ("schedule", encode(Schedule(env_transitions=4096)))]}  # fmt: skip
    service = scripted(sim_script(act, last=5, hooks=hooks))
    shell = SafetyShell(service, SafetyLoopConfig(num_envs=B, watchdog_s=5.0))
    assert shell.run() == 0
    commands = of(service.published, "command")
    assert [c.header.step for c in commands] == list(range(6))
    assert all(c.mode == CommandMode.TRACK for c in commands)
    for command in commands:
        _, decoded = decode_command(command, B, S, CONTROL_DT)  # what the sim will execute
        assert np.isfinite(decoded.q_ref).all()
    rejections = [e for e in of(service.published, "event")
                  if e.kind == SafetyEventKind.REJECTED_NONFINITE]  # fmt: skip
    assert len(rejections) == 1 and rejections[0].header.step == 2
    assert from_tensor(rejections[0].env_ids).tolist() == [0]
    assert shell.env_transitions == 4096
    assert dict(service.drops.counts) == {("hamnet/t/policy/0/action", "decode"): 1}


def test_an_action_of_another_action_space_is_dropped() -> None:
    """A policy trained on paddle twists must never run as joint residuals: the joint-space
    filter drops its action (counted under `space`) and answers the state with the next
    action of its own space; a paddle-space decoder takes it and refuses a joint one."""
    twist = policy_action(1, np.zeros((B, 21)))
    twist.action_space = "paddle"
    with pytest.raises(PayloadError) as error:
        decode_action(parse(PolicyAction, encode(twist)))
    assert error.value.reason == "space" and "paddle" in str(error.value)
    assert decode_action(twist, "paddle").action_space == "paddle"
    with pytest.raises(PayloadError):
        decode_action(policy_action(1, np.zeros((B, 21))), "paddle")
    hooks = {1: lambda: [("state", encode(robot_state(1))), ("action", encode(twist))]}
    service = scripted(sim_script(lambda step: np.zeros((B, 21)), last=3, hooks=hooks))
    shell = SafetyShell(service, SafetyLoopConfig(num_envs=B, watchdog_s=5.0))
    assert shell.run() == 0
    assert [c.header.step for c in of(service.published, "command")] == [0, 1, 2, 3]
    assert dict(service.drops.counts) == {("hamnet/t/policy/0/action", "space"): 1}


def test_a_restarted_sim_starts_every_episode_afresh() -> None:
    """A new run of the sim at step 0 with the old episode ids and episode steps (a sim
    restarted with the same seed): its command is a fresh filter's, not one that smooths on
    from the old run's residuals; and it is answered although the old run was at step 3."""
    action = np.full((B, 21), 0.5, np.float32)
    old = [m for k in range(4) for m in (("state", encode(robot_state(k, run=1))),
                                         ("action", encode(policy_action(k, action))))]  # fmt: skip
    q = np.tile(Q_HOME, (B, 1)) + 0.05
    items = iter([*old, ("state", encode(robot_state(0, q, episode_step=4, run=2))),
                  ("action", encode(policy_action(0, action)))])  # fmt: skip
    service = scripted(lambda published: next(items, "end"))
    shell = SafetyShell(service, SafetyLoopConfig(num_envs=B, watchdog_s=5.0))
    assert shell.run() == 0
    commands = of(service.published, "command")
    assert [c.header.step for c in commands] == [0, 1, 2, 3, 0]
    fresh = SafetyFilter(q).command(action.astype(np.float64), q, np.zeros((B, J)), 0)
    _, restarted = decode_command(commands[-1], B, S, CONTROL_DT)
    np.testing.assert_allclose(restarted.q_ref, fresh.q_ref, atol=1e-6)


def test_watchdog_brakes_without_actions_and_resumes_when_they_return() -> None:
    """The policy is silent for states 3-5: state 3 waits out the watchdog (one
    WATCHDOG_STOP event) and is answered with a STOP command, states 4-5 at once; an action
    for state 5, late, revives the policy, and state 6 is tracked again."""
    silent = {3, 4, 5}
    late = []

    def act(step: int) -> np.ndarray | None:
        return None if step in silent else np.zeros((B, 21), np.float32)

    def late_action():
        late.append(time.monotonic())
        return [("action", encode(policy_action(5, np.zeros((B, 21), np.float32))))]

    service = scripted(sim_script(act, last=7, hooks={6: late_action}))
    shell = SafetyShell(service, SafetyLoopConfig(num_envs=B, watchdog_s=0.2))
    started = time.monotonic()
    shell.run()
    commands = of(service.published, "command")
    assert [c.header.step for c in commands] == list(range(8))
    modes = [c.mode for c in commands]
    assert modes[:3] == [CommandMode.TRACK] * 3
    assert modes[3:6] == [CommandMode.STOP] * 3
    assert modes[6:] == [CommandMode.TRACK] * 2
    watchdog = [e for e in of(service.published, "event")
                if e.kind == SafetyEventKind.WATCHDOG_STOP]  # fmt: skip
    assert len(watchdog) == 1 and watchdog[0].header.step == 3
    assert from_tensor(watchdog[0].env_ids).tolist() == [0, 1]
    assert 0.2 <= late[0] - started < 1.0  # one watchdog wait, not one per silent state


def test_estop_latches_ignores_actions_until_reset() -> None:
    """`stop` while state 2 is sent: states 2-4 get STOP commands although actions arrive;
    `reset` at state 5: tracking again. Each request publishes its event once."""
    holder: list[SafetyShell] = []

    def request(command: str):
        return lambda: holder[0].estop.request(command) and None

    hooks = {2: request("stop"), 5: request("reset")}
    act = lambda step: np.zeros((B, 21), np.float32)
    service = scripted(sim_script(act, last=6, hooks=hooks))
    shell = SafetyShell(service, SafetyLoopConfig(num_envs=B, watchdog_s=5.0))
    holder.append(shell)
    shell.run()
    commands = of(service.published, "command")
    assert [c.header.step for c in commands] == list(range(7))
    assert [c.mode for c in commands] == [CommandMode.TRACK] * 2 + [CommandMode.STOP] * 3 + [
        CommandMode.TRACK
    ] * 2
    kinds = [e.kind for e in of(service.published, "event")]
    assert kinds.count(SafetyEventKind.ESTOP_LATCHED) == 1
    assert kinds.count(SafetyEventKind.ESTOP_RESET) == 1
    assert SafetyEventKind.WATCHDOG_STOP not in kinds


def test_statistics_event_carries_every_stage() -> None:
    act = lambda step: np.full((B, 21), 5.0, np.float32)  # saturating actions
    service = scripted(sim_script(act, last=3))
    config = SafetyLoopConfig(num_envs=B, watchdog_s=5.0, stats_period_s=0.0)
    SafetyShell(service, config).run()
    events: list[SafetyEvent] = of(service.published, "event")
    stats = [e for e in events if e.kind == SafetyEventKind.SAFETY_EVENT_KIND_UNSPECIFIED]
    assert stats and {s.stage for s in stats[0].stages} >= {"nonfinite_guard", "joint_limits"}
    assert sum(s.commands for e in stats for s in e.stages if s.stage == "nonfinite_guard") == 8
    clipped = [e for e in events if e.kind == SafetyEventKind.CLIPPED_MAGNITUDE]
    assert len(clipped) == 1  # rate-limited: one per clip_event_period_s


def test_state_sent_again_while_waiting_keeps_its_watchdog_deadline() -> None:
    """The lock-step sim sends its state again every `resend_s` while it waits; when each
    copy restarted the wait, resends faster than the watchdog kept it from ever firing (a
    dead policy stalled the sim instead of braking it). A copy of an answered state gets
    the same command again, not a second filter call."""
    last_copy = [time.monotonic()]
    give_up = time.monotonic() + 2.0

    def script(published):
        if len(of(published, "command")) >= 2 or time.monotonic() > give_up:
            return "end"
        if time.monotonic() - last_copy[0] >= 0.05:  # a copy of state 0 every 50 ms
            last_copy[0] = time.monotonic()
            return "state", encode(robot_state(0))
        return None

    service = scripted(script)
    started = time.monotonic()
    SafetyShell(service, SafetyLoopConfig(num_envs=B, watchdog_s=0.2)).run()
    commands = of(service.published, "command")
    assert time.monotonic() - started < 1.0
    assert [c.header.step for c in commands] == [0, 0] and commands[0] == commands[1]
    assert commands[0].mode == CommandMode.STOP
    kinds = [e.kind for e in of(service.published, "event")]
    assert kinds == [SafetyEventKind.WATCHDOG_STOP]


def test_watchdog_fires_under_a_free_running_executor() -> None:
    """A real-time executor sends state k+1 a period after state k whether or not k was
    answered. When each new state restarted the wait, a watchdog longer than the period
    never fired and no command was ever sent (seen in the demo stack)."""
    sent = [time.monotonic()]
    step = [0]
    give_up = time.monotonic() + 2.0

    def script(published):
        if len(of(published, "command")) >= 3 or time.monotonic() > give_up:
            return "end"
        if time.monotonic() - sent[0] >= 0.1:  # one state per 100 ms policy period
            sent[0] = time.monotonic()
            step[0] += 1
            return "state", encode(robot_state(step[0]))
        return None

    service = scripted(script)
    SafetyShell(service, SafetyLoopConfig(num_envs=B, watchdog_s=0.25)).run()
    commands = of(service.published, "command")
    assert len(commands) == 3 and all(c.mode == CommandMode.STOP for c in commands)
    watchdog = [e for e in of(service.published, "event")
                if e.kind == SafetyEventKind.WATCHDOG_STOP]  # fmt: skip
    assert len(watchdog) == 1 and watchdog[0].header.step in (3, 4)
