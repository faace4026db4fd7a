"""Rollout chunks of the service chain (`hamnet.policy.chunking`) from hand-made steps and
transitions: exact fields of a complete chunk, the bootstrap of a timeout, gaps that drop
and count, arrival in either order, bounded memory, the Transition's decoding, and the
policy shell publishing a chunk the trainer decodes into what it served."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hamnet.policy.chunking import ChunkAssembler
from hamnet.policy.messages import decode_transition
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import NetworkInputs
from hamnet.policy.registry import build
from hamnet.policy.shell import PolicyLoopConfig, PolicyShell
from hamnet.proto.trainer_pb2 import Schedule
from hamnet.runtime.codec import encode
from hamnet.runtime.service import ServiceIdentity
from hamnet.runtime.shell_config import ComputeConfig
from hamnet.runtime.tensor import PayloadError, from_tensor
from hamnet.sim.env import StepResult
from hamnet.sim.shell import encode_transition
from hamnet.task.rewards import REWARD_NAMES
from hamnet.trainer.storage.rollout_chunks import decode_rollout
from tests.policy.wire import state_message, tokens_message
from tests.scripted import ScriptedService, wire

T, B, A, R = 3, 2, 21, len(REWARD_NAMES)
IDS = np.array([10, 20])


def inputs(k: int) -> PolicyInputs:
    """Inputs of step k whose every entry says which step and row it is: 100 k + row."""
    rows = 100.0 * k + torch.arange(B, dtype=torch.float32)  # (B,)
    tokens = rows[:, None, None].expand(B, 2, 3).clone()  # (B, N, D)
    piece = rows[:, None].expand(B, 4).clone()  # (B, 4)
    observation = NetworkInputs(piece, piece + 0.1, piece + 0.2, piece + 0.3)
    return PolicyInputs(observation, tokens, tokens + 0.5, tokens + 0.25)


def add_step(chunks: ChunkAssembler, k: int, ids=IDS, version: int = 1) -> list:
    """Serve step k: action k + row, log_prob -k, values k + 0.1 term."""
    rows = k + torch.arange(B, dtype=torch.float32)
    values = k + 0.1 * torch.arange(R, dtype=torch.float32).expand(B, R)
    return chunks.add_step(k, ids, inputs(k), rows[:, None].expand(B, A), -rows, values, version)


def add_transition(chunks: ChunkAssembler, k: int, ids=IDS, truncated=(), terminated=()) -> list:
    """The transition of step k: reward terms 10 k + term; flags at the given rows."""
    rewards = 10.0 * k + np.tile(np.arange(R, dtype=np.float32), (B, 1))
    flags = lambda rows: np.isin(np.arange(B), rows)
    return chunks.add_transition(
        k, ids, rewards, flags(terminated), flags(truncated), flags(terminated)
    )


def test_a_complete_chunk_has_every_field_time_major() -> None:
    """Steps 5..7 with their transitions and the served step 8 make one chunk whose fields
    are the hand-made ones, step t's input rows at [t B, (t + 1) B)."""
    chunks = ChunkAssembler(T)
    out = []
    for k in range(5, 8):
        out += add_step(chunks, k, version=3 if k == 6 else 2)
        out += add_transition(chunks, k, terminated=[1] if k == 6 else [])
    assert out == []
    (chunk,) = add_step(chunks, 8, version=3)
    r = chunk.rollout
    assert chunk.first_step == 5 and chunk.version == 2  # the oldest version that acted
    steps = torch.tensor([5.0, 6.0, 7.0])
    rows = steps[:, None] + torch.arange(B)  # (T, B)
    torch.testing.assert_close(r.actions, rows[..., None].expand(T, B, A))
    torch.testing.assert_close(r.log_prob, -rows)
    values = steps[:, None, None] + 0.1 * torch.arange(R).float()  # (T, 1, R)
    torch.testing.assert_close(r.values, values.expand(T, B, R))
    rewards = 10 * steps[:, None, None] + torch.arange(R).float()  # (T, 1, R)
    torch.testing.assert_close(r.rewards, rewards.expand(T, B, R))
    torch.testing.assert_close(r.next_values, (8 + 0.1 * torch.arange(R).float()).expand(B, R))
    dones = torch.tensor([[False, False], [False, True], [False, False]])
    assert torch.equal(r.dones, dones) and torch.equal(r.success, dones)
    assert not r.final_values.any()  # a termination is not bootstrapped
    expected_rows = (100 * steps[:, None] + torch.arange(B)).reshape(T * B)
    torch.testing.assert_close(r.inputs.observation.context[:, 0], expected_rows)
    torch.testing.assert_close(r.inputs.local_tokens[:, 0, 0], expected_rows + 0.5)
    assert r.inputs.env_code is None and r.inputs.memory is None


def test_a_timeout_is_bootstrapped_with_the_value_of_its_last_acted_state() -> None:
    chunks = ChunkAssembler(T)
    for k in range(T):
        add_step(chunks, k)
        add_transition(chunks, k, truncated=[0] if k == 1 else [], terminated=[1] if k == 2 else [])
    (chunk,) = add_step(chunks, T)
    final = chunk.rollout.final_values
    torch.testing.assert_close(final[1, 0], chunk.rollout.values[1, 0])
    final[1, 0] = 0
    assert not final.any()
    assert chunk.rollout.dones[1, 0] and chunk.rollout.dones[2, 1]


@pytest.mark.parametrize("transition_first", [True, False])
def test_a_transition_may_arrive_before_or_after_its_step(transition_first: bool) -> None:
    chunks, out = ChunkAssembler(T), []
    for k in range(2 * T + 1):
        pair = (add_transition, add_step) if transition_first else (add_step, add_transition)
        for add in pair:
            out += add(chunks, k) if k < 2 * T or add is add_step else []
    assert [c.first_step for c in out] == [0, T]
    assert chunks.dropped == dict.fromkeys(chunks.dropped, 0)


def test_transitions_arriving_late_complete_chunks_in_order() -> None:
    """Transitions of the second chunk come first; the first chunk's last one releases both."""
    chunks = ChunkAssembler(T, window=3 * T)
    for k in range(2 * T + 1):
        add_step(chunks, k)
    assert [add_transition(chunks, k) for k in range(T, 2 * T)] == [[]] * T
    out = [c for k in range(T) for c in add_transition(chunks, k)]
    assert [c.first_step for c in out] == [0, T]


def test_a_missing_step_drops_the_partial_chunk_and_the_next_starts_after_it() -> None:
    chunks, out = ChunkAssembler(T), []
    for k in (0, 1, 3, 4, 5, 6):  # step 2 was never served
        out += add_step(chunks, k) + add_transition(chunks, k)
    assert chunks.dropped["missing_step"] == 1
    assert [c.first_step for c in out] == [3]


def test_a_transition_missing_for_a_window_drops_the_chunk() -> None:
    chunks, out = ChunkAssembler(T, window=2), []
    for k in range(8):
        out += add_step(chunks, k) + (add_transition(chunks, k) if k != 1 else [])
    assert chunks.dropped["missing_transition"] == 1
    assert [c.first_step for c in out] == [2]
    assert add_transition(chunks, 1) == [] and chunks.ignored == 1  # too late now
    assert max(chunks.steps) - min(chunks.steps) <= chunks.window + T  # memory stays bounded


def test_episode_ids_that_disagree_drop_the_chunk() -> None:
    chunks, out = ChunkAssembler(T), []
    for k in range(8):
        ids = np.array([10, 21]) if k == 1 else IDS
        out += add_step(chunks, k) + add_transition(chunks, k, ids=ids)
    assert chunks.dropped["episode_mismatch"] == 1
    assert [c.first_step for c in out] == [2]


def test_transitions_without_served_steps_are_not_kept_forever() -> None:
    chunks = ChunkAssembler(T, window=2)
    for k in range(100):
        add_transition(chunks, k)
    assert len(chunks.outcomes) == chunks.window + T


def step_result(rewards: np.ndarray, terminated, truncated, success) -> StepResult:
    """What `VectorEnv.step` returns, as far as a Transition carries it (episodes IDS)."""
    flag = lambda rows: np.isin(np.arange(B), rows)
    return StepResult(
        observation=None, final_observation=None, reward_terms=rewards.astype(np.float32),
        terminated=flag(terminated), truncated=flag(truncated), success=flag(success),
        reason=np.zeros(B, np.int8), episode_ids=IDS, reset_ids=np.arange(0),
    )  # fmt: skip


def test_a_transition_decodes_to_what_the_sim_sent() -> None:
    result = step_result(np.random.default_rng(0).normal(size=(B, R)), [0], [1], [0])
    decoded = decode_transition(wire(encode_transition(result, REWARD_NAMES, 7)))
    assert decoded.step == 7 and np.array_equal(decoded.episode_ids, IDS)
    np.testing.assert_array_equal(decoded.reward_terms, result.reward_terms)
    for name in ("terminated", "truncated", "success"):
        np.testing.assert_array_equal(getattr(decoded, name), getattr(result, name))
    with pytest.raises(PayloadError, match="reward terms"):
        decode_transition(wire(encode_transition(result, REWARD_NAMES[::-1], 7)))


def test_the_shell_publishes_what_it_served_as_a_chunk_the_trainer_decodes() -> None:
    """Step 0 served before the trainer is heard (its schedule) joins no chunk; steps 1..T
    with their transitions and step T + 1 make one RolloutChunk whose actions and values are
    the published actions' and whose inputs the trainer's policy reads. With
    `rollout_horizon` 0 the shell neither listens to transitions nor publishes chunks; while
    no learner subscribes to the chunks it serves every step and sends no chunk."""
    policy = build("hamnet", seed=0)
    messages = []
    for k in range(T + 2):
        messages += [("state", state_message(k, B, IDS)), ("tokens", tokens_message(k, B, IDS))]
        transition = encode_transition(
            step_result(np.full((B, R), k), [], [1], []), REWARD_NAMES, k
        )
        messages += [("transition", transition)] if k <= T else []
        messages += [("schedule", Schedule(env_transitions=0))] if k == 0 else []

    def published(horizon: int, subscribed: bool = True) -> list[tuple[str, object]]:
        items = iter([m for m in messages if horizon or m[0] != "transition"])  # off: unheard

        def script(_) -> tuple[str, bytes] | str:
            item = next(items, None)
            return "end" if item is None else (item[0], encode(item[1]))

        service = ScriptedService(script, identity=ServiceIdentity("policy", "0"),
                                  subscribed=lambda: subscribed)  # fmt: skip
        config = PolicyLoopConfig(compute=ComputeConfig(seed=1), rollout_horizon=horizon)
        PolicyShell(service, policy, 4, config).run()
        return service.published

    assert [topic for topic, _ in published(0)] == ["action"] * (T + 2)
    assert [topic for topic, _ in published(T, subscribed=False)] == ["action"] * (T + 2)
    out = published(T)
    actions = [message for topic, message in out if topic == "action"]
    (chunk,) = [message for topic, message in out if topic == "rollout"]
    assert chunk.header.policy_version == 4 and chunk.horizon == T
    rollout = decode_rollout(chunk, policy)
    sent = lambda name: torch.stack([torch.tensor(from_tensor(getattr(m, name))) for m in actions])
    torch.testing.assert_close(rollout.actions, sent("action")[1 : T + 1])
    torch.testing.assert_close(rollout.values, sent("values")[1 : T + 1])
    torch.testing.assert_close(rollout.next_values, sent("values")[T + 1])
    torch.testing.assert_close(rollout.final_values[:, 1], rollout.values[:, 1])
    assert rollout.dones[:, 1].all() and not rollout.dones[:, 0].any()
    torch.testing.assert_close(rollout.rewards[:, 0, 0], torch.arange(1, T + 1).float())
