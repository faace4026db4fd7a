"""The policy shell driven by scripted messages (no network): decoding, pairing by step,
answers equal to the core's, resends, EnvCode from scenes, and hot reload that swaps
between batches and refuses bad weights while the old ones keep serving."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hamnet.policy.messages import decode_state, decode_tokens, robot_observation
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import assemble
from hamnet.policy.registry import build, with_changes
from hamnet.policy.serving import PolicyLoopConfig
from hamnet.policy.shell import PolicyShell
from hamnet.policy.weights import to_bytes
from hamnet.runtime.codec import encode
from hamnet.runtime.service import ServiceIdentity
from hamnet.runtime.tensor import PayloadError, to_tensor
from hamnet.task.physics import PHYSICS_PARAM_NAMES
from tests.policy.inputs import informed, random_robot
from tests.policy.wire import announcement, scene_message, state_message, tokens_message
from tests.scripted import ScriptedService, wire

B = 3


def expected(policy, step: int, env_code: np.ndarray | None = None, previous=None) -> torch.Tensor:
    """The deterministic action for step `step` computed by the core directly, after the
    action `previous` (B, 21) of the same episodes (None: their first step)."""
    previous = torch.zeros(B, 21) if previous is None else previous
    g = torch.Generator().manual_seed(10_000 + step)
    obj, local, whole = (torch.randn(B, 17, 128, generator=g) for _ in range(3))
    inputs = PolicyInputs(
        assemble(random_robot(B, seed=step), previous, policy.config.observation),
        obj, local, whole,
        None if env_code is None else torch.tensor(env_code), policy.initial_memory(B),
    )  # fmt: skip
    with torch.no_grad():
        return policy.act(inputs, deterministic=True).action


def run(
    policy, messages: list[tuple[str, object]], pose_noise: bool = False
) -> tuple[list, PolicyShell]:
    """Feed `messages` to a shell serving `policy` (version 0); returns published actions."""
    items = iter(messages)

    def script(published):
        item = next(items, None)
        return "end" if item is None else (item[0], encode(item[1]))

    service = ScriptedService(script, identity=ServiceIdentity("policy", "0"))
    config = PolicyLoopConfig(deterministic=True, student_pose_noise=pose_noise)
    shell = PolicyShell(service, policy, 0, config)
    shell.run()
    return [message for topic, message in service.published if topic == "action"], shell


def test_state_and_tokens_decode_to_what_was_sent() -> None:
    width = len(PHYSICS_PARAM_NAMES)
    state = decode_state(wire(state_message(5, B)), privileged=True, physics_params=width)
    robot = random_robot(B, seed=5)
    assert state.step == 5 and state.episode_ids.shape == (B,)
    for name in ("q", "ee_pos_rot6d", "object_velocity", "physics_params"):
        torch.testing.assert_close(
            getattr(robot_observation(state, True), name), getattr(robot, name)
        )
    tokens = decode_tokens(wire(tokens_message(5, B)), 17, 128)
    assert [t.shape for t in tokens.tokens] == [(B, 17, 128)] * 3


def test_a_student_reads_the_pose_estimate_and_never_the_privileged_block() -> None:
    """On the real robot there is no privileged block: a teacher refuses such a state, a
    student takes its object pose from `object_pose_estimate` (moved here to tell them apart)."""
    message = state_message(1, B)
    message.ClearField("privileged")
    estimate = np.tile(np.array([0.6, 0.1, 0.2, 1.0, 0.0, 0.0, 0.0], np.float32), (B, 1))
    to_tensor(estimate, message.object_pose_estimate)
    width = len(PHYSICS_PARAM_NAMES)
    with pytest.raises(PayloadError, match="privileged"):
        decode_state(message, privileged=True, physics_params=width)
    student = robot_observation(
        decode_state(message, privileged=False, physics_params=width), False
    )
    torch.testing.assert_close(student.object_pose, torch.from_numpy(estimate))
    assert student.object_pose is not None and student.physics_params is None


def test_pairs_by_step_in_any_order_and_a_lost_half_blocks_nothing() -> None:
    policy = build("hamnet", seed=0)
    actions, shell = run(policy, [
        ("tokens", tokens_message(0, B)), ("state", state_message(0, B)),
        ("state", state_message(1, B)),  # its tokens never come
        ("state", state_message(2, B)), ("tokens", tokens_message(2, B)),
        ("tokens", tokens_message(1, B)),  # too late: step 2 is answered
    ])  # fmt: skip
    assert [a.header.step for a in actions] == [0, 2]
    previous = None  # step 2 follows the last answered action, step 0's
    for message in actions:
        got = torch.from_numpy(np.frombuffer(message.action.data, np.float32).reshape(B, 21).copy())
        want = expected(policy, message.header.step, previous=previous)
        torch.testing.assert_close(got, want, atol=1e-5, rtol=1e-5)
        previous = got
        assert message.deterministic and tuple(message.module_weights.shape) == (B, 10, 8)
        assert message.action_space == "joint"
        assert tuple(message.values.shape) == (B, 3) and tuple(message.log_prob.shape) == (B,)
    assert shell.pairing.dropped["superseded"] == 1 and shell.counts["stale"] == 1


def test_actions_say_the_action_space_of_the_weights() -> None:
    """A policy trained on paddle twists says so in every action, so that a safety filter
    reading joint residuals drops them (`hamnet.safety.messages.decode_action`)."""
    policy = build("hamnet", with_changes("hamnet", action_space="paddle"), seed=0)
    actions, _ = run(policy, [("state", state_message(0, B)), ("tokens", tokens_message(0, B))])
    assert [a.action_space for a in actions] == ["paddle"]


def test_a_restarted_sim_is_followed_at_once_and_a_far_future_step_is_refused() -> None:
    """A new sim counts from 0 again: its first state is answered although the old run's
    step 5 was answered last, with the episodes' carry started afresh; a state of the same
    run 10^12 steps ahead is refused (adopting it would make every real step stale). A late
    state of the old run switches back, and the new run's next state switches again: runs
    are never retired, or a forger's run could shut the real sim out for good."""
    policy = build("hamnet", seed=0)
    old = [m for k in range(6) for m in (("state", state_message(k, B, run=7)),
                                         ("tokens", tokens_message(k, B)))]  # fmt: skip
    far = 10**12
    actions, shell = run(policy, [
        *old,
        ("state", state_message(far, B, episode_step=np.zeros(B), run=7)),
        ("tokens", tokens_message(far, B)),
        ("state", state_message(0, B, run=8)), ("tokens", tokens_message(0, B)),
        ("state", state_message(4, B, run=7)),  # late, from the old run
        ("state", state_message(1, B, run=8)), ("tokens", tokens_message(1, B)),
    ])  # fmt: skip
    assert [a.header.step for a in actions] == [0, 1, 2, 3, 4, 5, 0, 1]
    first = torch.from_numpy(
        np.frombuffer(actions[6].action.data, np.float32).reshape(B, 21).copy()
    )
    torch.testing.assert_close(first, expected(policy, 0), atol=1e-5, rtol=1e-5)  # no carry
    assert shell.counts["implausible"] == 2 and shell.counts["restarts"] == 3


def test_a_resent_state_gets_the_same_answer_again() -> None:
    policy = build("mlp", seed=0)
    actions, _ = run(policy, [("state", state_message(0, B)), ("tokens", tokens_message(0, B)),
                              ("state", state_message(0, B))])  # fmt: skip
    assert len(actions) == 2 and actions[0] == actions[1]


def test_envcode_oracle_reads_the_scene_of_each_environment() -> None:
    policy = build("hamnet-envcode", seed=0)
    code = np.random.default_rng(0).standard_normal((B, 25)).astype(np.float32)
    actions, _ = run(policy, [("scene", scene_message([2], code[2:])),
                              ("scene", scene_message([0, 1], code[:2])),
                              ("state", state_message(0, B)), ("tokens", tokens_message(0, B))])  # fmt: skip
    got = np.frombuffer(actions[0].action.data, np.float32).reshape(B, 21)
    torch.testing.assert_close(
        torch.from_numpy(got.copy()), expected(policy, 0, code), atol=1e-5, rtol=1e-5
    )


def test_hot_reload_swaps_between_batches_and_bad_weights_keep_the_old_ones() -> None:
    serving, newer = build("hamnet", seed=0), build("hamnet", seed=1)
    corrupt = announcement(newer, 2)
    corrupt.sha256 = "0" * 64
    messages = [
        ("state", state_message(0, B)),
        ("tokens", tokens_message(0, B)),
        ("weights", announcement(newer, 1)),
        ("state", state_message(1, B)),
        ("tokens", tokens_message(1, B)),
        ("weights", corrupt),  # sha256 mismatch
        ("weights", announcement(build("mlp", seed=0), 3)),  # another architecture
        ("weights", announcement(newer, 0)),  # not newer
        (
            "weights",
            announcement(newer, 1),
        ),  # a repeat of the served version: ignored, not rejected
        ("weights", announcement(newer, 4, data=to_bytes(newer, 5))),  # metadata disagrees
        ("weights", announcement(newer, 6, data=b"garbage")),
        ("state", state_message(2, B)),
        ("tokens", tokens_message(2, B)),
    ]
    actions, shell = run(serving, messages)
    assert [(a.header.step, a.header.policy_version) for a in actions] == [(0, 0), (1, 1), (2, 1)]
    reference = {0: build("hamnet", seed=0), 1: newer, 2: newer}
    previous = None
    for message in actions:
        got = torch.from_numpy(np.frombuffer(message.action.data, np.float32).reshape(B, 21).copy())
        want = expected(reference[message.header.step], message.header.step, previous=previous)
        torch.testing.assert_close(got, want, atol=1e-5, rtol=1e-5)
        previous = got
    assert shell.counts["rejected"] == 5 and shell.version == 1


def test_student_memory_restarts_with_each_episode() -> None:
    """A new episode id must zero that environment's memory: the student's action for the
    first state of an episode equals the action of a fresh student."""
    policy = build("student", seed=0)
    actions, _ = run(policy, [
        ("state", state_message(0, B, episode_ids=[0, 0, 0], episode_step=[0, 0, 0])),
        ("tokens", tokens_message(0, B)),
        ("state", state_message(1, B, episode_ids=[0, 7, 0], episode_step=[1, 0, 1])),
        ("tokens", tokens_message(1, B, episode_ids=[0, 7, 0])),
    ])  # fmt: skip
    got = np.frombuffer(actions[1].action.data, np.float32).reshape(B, 21)
    fresh = expected(policy, 1).numpy()
    np.testing.assert_allclose(got[1], fresh[1], atol=1e-5)
    assert not np.allclose(got[0], fresh[0], atol=1e-4)


def test_a_student_against_the_sim_sees_a_noisy_pose_unless_told_otherwise() -> None:
    """The sim's true pose stands in for the estimator's: with the error model on (the
    default) the student's action differs from the one on the exact pose; off, it equals it."""
    policy = informed("student")
    messages = [("state", state_message(0, B)), ("tokens", tokens_message(0, B))]
    exact, _ = run(policy, messages)
    noisy, _ = run(policy, messages, pose_noise=True)
    action = lambda m: np.frombuffer(m.action.data, np.float32).reshape(B, 21)
    np.testing.assert_allclose(action(exact[0]), expected(policy, 0).numpy(), atol=1e-5)
    assert not np.allclose(action(noisy[0]), action(exact[0]), atol=1e-4)


def test_a_student_served_reads_the_mean_of_its_last_pose_readings() -> None:
    """Weights with `pose_readings` 2: the service's second action is the core's with the
    object pose set by hand to the mean of the two estimates sent, not the newest alone."""
    import dataclasses

    from hamnet.policy import inputs as builder

    policy = informed("student", pose_readings=2)
    actions, _ = run(policy, [
        ("state", state_message(0, B)), ("tokens", tokens_message(0, B)),
        ("state", state_message(1, B)), ("tokens", tokens_message(1, B)),
    ])  # fmt: skip
    served = np.frombuffer(actions[1].action.data, np.float32).reshape(B, 21)
    old, new = random_robot(B, 0).object_pose, random_robot(B, 1).object_pose
    side = torch.where((old[:, 3:] * new[:, 3:]).sum(-1, keepdim=True) < 0, -1.0, 1.0)
    rotation = torch.nn.functional.normalize(old[:, 3:] * side + new[:, 3:], dim=-1)
    mean = torch.cat(((old[:, :3] + new[:, :3]) / 2, rotation), -1)

    def second_action(pose: torch.Tensor) -> np.ndarray:
        """The core's action at step 1 reading `pose`, after step 0 on its own estimate."""
        carry = builder.initial_carry(policy, B)
        for step, read in ((0, old), (1, pose)):
            carry = builder.begin_step(
                carry, torch.zeros(B, dtype=torch.int64), torch.full((B,), step)
            )
            g = torch.Generator().manual_seed(10_000 + step)
            tokens = tuple(torch.randn(B, 17, 128, generator=g) for _ in range(3))
            robot = dataclasses.replace(random_robot(B, step), object_pose=read)
            with torch.no_grad():
                out = policy.act(builder.policy_inputs(policy.config, carry, robot, tokens), True)
            carry = builder.end_step(carry, out.action, out.memory)
        return out.action.numpy()

    np.testing.assert_allclose(served, second_action(mean), atol=1e-5)
    assert not np.allclose(served, second_action(new), atol=1e-4)
