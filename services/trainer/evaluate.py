"""Success rate of a policy acting with its mean (no exploration noise) on held-out seeds:
the figure a learning result reports (`final_success_rate`).

The episodes are drawn from the same stage as training but from another seed, so no scene,
object or start of the evaluation was seen in training. Every environment plays exactly one
episode, its first, to its end: counting whichever episodes end first would favour the short
ones, and successes are short.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hamnet.policy.policy import Policy
from hamnet.trainer.runner import RunConfig, build_workers

HELD_OUT_SEED_OFFSET = 1_000_003
"""Added to the training seed for evaluation environments (a prime, far from any run seed)."""


def success_rate(policy: Policy, config: RunConfig, episodes: int, env_transitions: int) -> float:
    """Fraction of `episodes` held-out episodes (one per environment) that succeeded.

    Args:
        policy: acts deterministically (the mean of its Gaussian).
        config: the run whose stage to use; its seed is offset (held out).
        episodes: how many episodes, one per environment.
        env_transitions: the schedule counter of the policy (safety's xi annealing).
    """
    sim = dataclasses.replace(config.sim, seed=config.seed + HELD_OUT_SEED_OFFSET, num_envs=episodes)
    held_out = dataclasses.replace(config, sim=sim)
    (worker,), _ = build_workers(held_out, groups=1)
    policy.eval()
    ended = np.zeros(episodes, dtype=bool)
    succeeded = np.zeros(episodes, dtype=bool)
    while not ended.all():
        rollout = worker.collect(policy, config.steps_per_rollout, env_transitions, deterministic=True)
        for dones, success in zip(rollout.dones.numpy(), rollout.success.numpy(), strict=True):
            first = dones & ~ended  # (B,) episodes ending for the first time
            succeeded |= first & success
            ended |= dones
    return float(succeeded.mean())
