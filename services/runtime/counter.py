"""The one counter every schedule is a function of, and its conversion from the authors' unit.

`env_transitions`: environment transitions summed over all environments and all workers,
the x-axis of the paper's training curves ("interaction steps aggregated across 1024 parallel
environments", paper lines 381 and 976). The trainer publishes it (Schedule.env_transitions);
the log-std decay (policy), the curricula (sim) and the xi and eps_x annealing (safety) are
pure functions of it, so they agree whatever the number of environments or workers.

The authors count vectorized steps of `AUTHORS_NUM_ENVS` environments instead: their
curriculum advances once per `env.step` of the whole batch (ham/scripts/env_wrappers.py:1216)
and their log std once per 1024 of those (ham/scripts/train.py:563-570), with 1024
environments (ham/src/ham/data/cfg/rss_train.yaml:10). `from_vectorized_steps` converts.
"""

from __future__ import annotations

UNIT = "env_transitions"
"""Name of the counter: on the wire (Schedule.env_transitions), in configs and in docs."""

AUTHORS_NUM_ENVS = 1024
"""Environments per vectorized step in the authors' training (rss_train.yaml:10, num_env)."""


def from_vectorized_steps(steps: float, num_envs: int = AUTHORS_NUM_ENVS) -> int:
    """env_transitions after `steps` vectorized steps of `num_envs` environments."""
    return round(steps * num_envs)
