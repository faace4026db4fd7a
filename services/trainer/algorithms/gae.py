"""Generalized advantage estimation per reward term (Schulman et al. 2016, Eq. 16).

HAMnet's critic has one value head per reward term (paper Sec. "Critic"; the authors'
`value_dim` heads, `rss_train.yaml:266`), so advantages and returns are computed for every
term separately over (T, B, R) and summed only for the actor. Truncated episodes are
bootstrapped by the caller: it adds gamma * V(final observation) to the reward of the
truncated step and marks the step done, as the authors' `interact` does
(`ham/src/ham/models/rl/v6/ppo.py:826-833`).
"""

from __future__ import annotations

import torch
from torch import Tensor


def gae(
    rewards: Tensor,
    values: Tensor,
    next_values: Tensor,
    dones: Tensor,
    gamma: float,
    gae_lambda: float,
) -> tuple[Tensor, Tensor]:
    """Advantages and value targets of T steps of B environments, per reward term.

    Args:
        rewards: (T, B, R) reward of each step, per term.
        values: (T, B, R) V(s_t) per term, as the acting policy computed them.
        next_values: (B, R) V(s_T) after the last step (bootstrap of the rollout's end).
        dones: (T, B) bool, the episode ended at step t (terminated or truncated): no value
            flows back across it.
        gamma: discount.
        gae_lambda: GAE's lambda.
    Returns:
        advantages (T, B, R) and returns (T, B, R) = advantages + values (the value targets).
    """
    if rewards.shape != values.shape or rewards.shape[1:] != next_values.shape:
        raise ValueError(
            f"shapes disagree: rewards {tuple(rewards.shape)}, values "
            f"{tuple(values.shape)}, next_values {tuple(next_values.shape)}"
        )
    if dones.shape != rewards.shape[:2]:
        raise ValueError(f"dones must be {tuple(rewards.shape[:2])}, got {tuple(dones.shape)}")
    keep = (~dones.bool()).to(rewards.dtype)[..., None]  # (T, B, 1)
    following = torch.cat([values[1:], next_values[None]], dim=0)  # (T, B, R): V(s_{t+1})
    deltas = rewards + gamma * keep * following - values  # (T, B, R), Eq. 12's TD errors
    advantages = torch.zeros_like(rewards)
    running = torch.zeros_like(next_values)  # (B, R)
    for t in range(rewards.shape[0] - 1, -1, -1):
        running = deltas[t] + gamma * gae_lambda * keep[t] * running
        advantages[t] = running
    return advantages, advantages + values
