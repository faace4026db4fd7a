"""Sequence batching of the recurrent student against a step-by-step rollout of its GRUs:
the same outputs with resets at t = 0 and mid-sequence, gradients through time inside an
episode and none across its start."""

from __future__ import annotations

import pytest
import torch

from hamnet.policy import inputs as builder
from hamnet.policy.registry import build
from hamnet.policy.rollout_record import cat_rows
from hamnet.trainer.algorithms.recurrent_unroll import episode_starts, evaluate_sequence
from tests.policy.inputs import random_robot

T, B = 5, 3
EPISODE_STEP = torch.tensor([
    [0, 3, 7],  # env 0 starts an episode at t = 0
    [1, 4, 8],
    [2, 0, 9],  # env 1 starts one mid-sequence
    [3, 1, 10],
    [4, 2, 11],  # env 2 never does
])  # fmt: skip
"""(T, B) policy steps since each episode started."""


def tokens(seed: int) -> tuple[torch.Tensor, ...]:
    g = torch.Generator().manual_seed(seed)
    return tuple(torch.randn(B, 17, 128, generator=g) for _ in range(3))


def acted_rollout(policy):
    """Step-by-step acting as the rollout worker does (`inputs.begin_step` zeroes the carry
    of new episodes), after one unrecorded step so the memory at t = 0 is not zero.
    Returns the stored inputs (T * B rows), the actions (T, B, A) and the acting outputs."""
    carry = builder.initial_carry(policy, B)
    ids = torch.zeros(B, dtype=torch.int64)
    carry = builder.begin_step(carry, ids, torch.ones(B))
    warm = policy.act(builder.policy_inputs(policy.config, carry, random_robot(B, 99), tokens(99)))
    carry = builder.end_step(carry, warm.action, warm.memory)
    stored, acted = [], []
    with torch.no_grad():
        for t in range(T):
            carry = builder.begin_step(carry, ids, EPISODE_STEP[t])
            inputs = builder.policy_inputs(policy.config, carry, random_robot(B, t), tokens(t))
            out = policy.act(inputs, deterministic=True)
            stored.append(inputs)
            acted.append(out)
            carry = builder.end_step(carry, out.action, out.memory)
    actions = torch.stack([out.action for out in acted])  # (T, B, A)
    return cat_rows(stored), actions, acted


def test_sequence_evaluation_equals_the_step_by_step_rollout():
    policy = build("student", seed=0).eval()
    inputs, actions, acted = acted_rollout(policy)
    assert inputs.memory[:B].abs().sum() > 0  # the reset at t = 0 has something to clear
    with torch.no_grad():
        seq = evaluate_sequence(policy, inputs, actions, EPISODE_STEP == 0)
    torch.testing.assert_close(seq.mean, actions, rtol=1e-5, atol=1e-5)  # deterministic: mean
    torch.testing.assert_close(
        seq.values, torch.stack([o.values for o in acted]), rtol=1e-5, atol=1e-5
    )
    torch.testing.assert_close(
        seq.log_prob, torch.stack([o.log_prob for o in acted]), rtol=1e-5, atol=1e-4
    )
    torch.testing.assert_close(
        seq.memories, torch.stack([o.memory for o in acted]), rtol=1e-5, atol=1e-5
    )


def test_a_missing_reset_changes_the_outputs():
    """The resets matter: without them the unroll carries env 0's and env 1's old memory."""
    policy = build("student", seed=0).eval()
    inputs, actions, _ = acted_rollout(policy)
    with torch.no_grad():
        seq = evaluate_sequence(policy, inputs, actions, torch.zeros(T, B, dtype=torch.bool))
    assert not torch.allclose(seq.mean[:, :2], actions[:, :2], atol=1e-4)
    torch.testing.assert_close(seq.mean[:, 2], actions[:, 2], rtol=1e-5, atol=1e-5)


def test_gradients_flow_within_an_episode_and_not_across_its_start():
    """d(last step's mean) / d(object tokens of every step): nonzero at every step of
    env 2's one episode and from env 1's new episode on, zero before env 1's start; and
    zero for env 0's stored memory, which its start at t = 0 replaces."""
    policy = build("student", seed=0)
    inputs, actions, _ = acted_rollout(policy)
    tokens = inputs.object_tokens.clone().requires_grad_(True)  # (T * B, N, D)
    memory = inputs.memory.clone().requires_grad_(True)
    inputs = type(inputs)(**{**vars(inputs), "object_tokens": tokens, "memory": memory})
    seq = evaluate_sequence(policy, inputs, actions, EPISODE_STEP == 0)
    seq.mean[-1].sum().backward()
    reach = tokens.grad.abs().sum((1, 2)).reshape(T, B) > 0  # (T, B)
    assert reach[:, 2].all() and reach[:, 0].all()
    assert reach[2:, 1].all() and not reach[:2, 1].any()
    flows = memory.grad[:B].abs().sum(1) > 0  # (B,)
    assert flows.tolist() == [False, False, True]


def test_episode_starts_follow_the_ends_before_them():
    dones = torch.tensor([[False, True], [True, False], [False, False]])
    starts = episode_starts(dones, torch.tensor([True, False]))
    assert starts.tolist() == [[True, False], [False, True], [True, False]]


def test_feed_forward_policies_and_ragged_sequences_are_refused():
    student = build("student", seed=0)
    inputs, actions, _ = acted_rollout(student)
    with pytest.raises(ValueError, match="no memory"):
        evaluate_sequence(build("hamnet", seed=0), inputs, actions, EPISODE_STEP == 0)
    with pytest.raises(ValueError, match="one \\(T, B\\) sequence"):
        evaluate_sequence(student, inputs, actions[:-1], EPISODE_STEP[:-1] == 0)
