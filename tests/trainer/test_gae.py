"""Per-term GAE against a hand-computed example."""

from __future__ import annotations

import pytest
import torch

from hamnet.trainer.algorithms.gae import gae


def test_per_term_gae_equals_the_hand_computed_example() -> None:
    """Two steps, one environment, two reward terms, gamma 0.5, lambda 0.5; the episode ends
    after step 0, so step 0 must not see V(s_1) and step 1 bootstraps from next_values.

    By hand, term 0: delta_1 = 1 + 0.5*4 - 2 = 1; A_1 = 1; delta_0 = 2 - 1 = 1 (done: no
    V(s_1)); A_0 = 1 (done: no A_1). Term 1: delta_1 = 0 + 0.5*(-2) - 0 = -1; A_1 = -1;
    delta_0 = 1 - 3 = -2; A_0 = -2.
    """
    rewards = torch.tensor([[[2.0, 1.0]], [[1.0, 0.0]]])  # (T=2, B=1, R=2)
    values = torch.tensor([[[1.0, 3.0]], [[2.0, 0.0]]])
    next_values = torch.tensor([[4.0, -2.0]])
    dones = torch.tensor([[True], [False]])
    advantages, returns = gae(rewards, values, next_values, dones, gamma=0.5, gae_lambda=0.5)
    torch.testing.assert_close(advantages, torch.tensor([[[1.0, -2.0]], [[1.0, -1.0]]]))
    torch.testing.assert_close(returns, advantages + values)


def test_lambda_mixes_future_td_errors_without_an_episode_end() -> None:
    """Three steps, no end, gamma 1, lambda 0.5, zero values: A_t = sum_k 0.5^k r_{t+k}."""
    rewards = torch.tensor([1.0, 2.0, 4.0]).reshape(3, 1, 1)
    zeros = torch.zeros(3, 1, 1)
    advantages, _ = gae(rewards, zeros, torch.zeros(1, 1), torch.zeros(3, 1, dtype=torch.bool), 1.0, 0.5)
    torch.testing.assert_close(advantages.flatten(), torch.tensor([1 + 1 + 1.0, 2 + 2.0, 4.0]))


def test_mismatched_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="dones"):
        gae(torch.zeros(2, 3, 1), torch.zeros(2, 3, 1), torch.zeros(3, 1), torch.zeros(3, 2), 0.9, 0.9)
