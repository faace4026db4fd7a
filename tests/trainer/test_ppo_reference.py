"""A shortened outside-PPO check (docs/trainer.md, "Checked against an outside PPO"): our
PPO core through `hamnet.trainer.gym_adapter` on Gymnasium's Reacher-v5, one seed, a third
of the full comparison's budget (benchmarks/ppo_reference.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hamnet.trainer.gym_adapter import GymPPO, GymPPOConfig

gymnasium = pytest.importorskip(
    "gymnasium",
    reason="the outside-PPO check needs the reference extra: pip install -e '.[reference]'",
)

ENV_STEPS = 100_352
"""49 rollouts of 2048 steps: where the reference's curve has done most of its climb."""
RANDOM_RETURN = -42.89
"""Uniform random actions, 1000 episodes on each of seeds 0-2 (docs/results/ppo-reference.json)."""
REFERENCE_RETURN = -8.78
"""Stable-Baselines3's PPO over the episodes ending at 89.7k-104.7k steps, mean of seeds 0-2
(-8.09 to -9.30 by seed; the JSON's `curves`, bins 12 and 13)."""
THRESHOLD = RANDOM_RETURN + 0.9 * (REFERENCE_RETURN - RANDOM_RETURN)
"""-12.2: 90% of the reference's improvement over random actions at this budget, the
issue's goal for the full comparison."""


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_our_ppo_learns_reacher_as_far_as_the_reference_at_100k_steps() -> None:
    """A regression in the core (GAE, the bootstrap of truncations, which every Reacher
    episode ends in, the losses, the update, the statistics) slows this curve. In the full
    comparison ours trails the reference by up to 3.7 early (its first 2048 steps only
    fill the statistics) and stays within 0.92 of it from 45k steps on; seed 0 is
    deterministic on one machine, so the margin is for other platforms' arithmetic."""
    from gymnasium.vector import AutoresetMode, SyncVectorEnv

    torch.set_num_threads(1)
    make = lambda: gymnasium.make("Reacher-v5")
    env = SyncVectorEnv([make], autoreset_mode=AutoresetMode.SAME_STEP)
    learner = GymPPO(env, GymPPOConfig(), seed=0)
    learner.train(ENV_STEPS)
    final = np.mean([r for step, r in learner.episodes if step > 0.9 * ENV_STEPS])
    assert final >= THRESHOLD, f"mean return {final:.2f} over the last 10% of steps"
