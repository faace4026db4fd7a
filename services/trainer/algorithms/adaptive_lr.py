"""The KL-adaptive learning rate (paper Table tab:PPO, "Learning rate schedule: KL-adaptive").

After each gradient step the rate is multiplied by `lr_factor` when the policy moved too
little (KL below kl_bounds[0] * kl_target) and divided by it when it moved too much (above
kl_bounds[1] * kl_target), within `lr_bounds`: the authors' rule
(`ham/src/ham/models/rl/adaptive_lr.py`, `update_lr_scale`).
"""

from __future__ import annotations

from hamnet.trainer.config import PPOConfig


def adapt_learning_rate(lr: float, kl: float, config: PPOConfig) -> float:
    """The learning rate after a step whose approximate KL(old || new) was `kl`."""
    if kl < config.kl_bounds[0] * config.kl_target:
        return min(lr * config.lr_factor, config.lr_bounds[1])
    if kl > config.kl_bounds[1] * config.kl_target:
        return max(lr / config.lr_factor, config.lr_bounds[0])
    return lr
