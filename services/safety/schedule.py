"""Annealing of the action-magnitude bound xi and the Cartesian bound eps_x over env_transitions.

Paper line 756: xi goes from xi_max to xi* by a geometric sequence with ratio
(xi*/xi_max)^(N_s/N_t), one factor every N_s steps, for N_t steps (Table tab:sim2real-params).
Lines 803-804 anneal eps_x from eps_x^max to eps_x without naming the shape; the same geometric
schedule is used, with its own `AnnealingConfig`. The trainer publishes only the counter,
env_transitions (hamnet.runtime.counter), on trainer/schedule; the values are pure functions
of it, keyed by SCHEDULE_NAMES in statistics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.safety.config import ActionMagnitudeConfig, AnnealingConfig, CartesianClipConfig

SCHEDULE_NAMES = ("xi_large", "xi_small", "eps_x")
"""Stable names of the annealed values."""


def annealing_exponent(env_transitions: int, annealing: AnnealingConfig) -> float:
    """Share of the way from start to end in the exponent: k*N_s/N_t, k whole intervals done,
    clamped to [0, 1]."""
    intervals = max(int(env_transitions) - annealing.start_step, 0) // annealing.interval
    return min(intervals * annealing.interval / annealing.num_steps, 1.0)


def geometric_anneal(env_transitions: int, start: float, end: float, annealing: AnnealingConfig) -> float:
    """start*(end/start)^(k*N_s/N_t): the k-th term of the paper's geometric sequence (line 756)."""
    return start * (end / start) ** annealing_exponent(env_transitions, annealing)


def xi_at(env_transitions: int, config: ActionMagnitudeConfig) -> tuple[float, float]:
    """xi for the large and the small joints at `env_transitions`, rad; xi_max throughout when disabled."""
    if not config.enabled:
        return config.xi_max_large, config.xi_max_small
    return (
        geometric_anneal(env_transitions, config.xi_max_large, config.xi_star_large, config.annealing),
        geometric_anneal(env_transitions, config.xi_max_small, config.xi_star_small, config.annealing),
    )


def eps_x_at(env_transitions: int, config: CartesianClipConfig) -> float:
    """epsilon_x at `env_transitions`, annealed from eps_x_max down to eps_x."""
    return geometric_anneal(env_transitions, config.eps_x_max, config.eps_x, config.annealing)


def per_joint(large: float, small: float, num_large_joints: int) -> np.ndarray:
    """A (J,) array: `large` on joints 1..num_large_joints, `small` on the rest."""
    values = np.full(NUM_JOINTS, small, dtype=np.float64)  # (J,)
    values[:num_large_joints] = large
    return values


@dataclass(frozen=True)
class ScheduleValues:
    """The annealed bounds at one env_transitions count."""

    xi_large: float
    """Action-magnitude bound of joints 1-4, rad per policy step."""
    xi_small: float
    """Action-magnitude bound of joints 5-7, rad per policy step."""
    eps_x: float
    """Cartesian bound on the predicted end-effector motion per policy step."""

    def as_dict(self) -> dict[str, float]:
        """The values keyed by SCHEDULE_NAMES."""
        return {name: getattr(self, name) for name in SCHEDULE_NAMES}


def schedule_values(
    env_transitions: int, magnitude: ActionMagnitudeConfig, cartesian: CartesianClipConfig
) -> ScheduleValues:
    """xi (both groups) and eps_x at `env_transitions` env_transitions."""
    xi_large, xi_small = xi_at(env_transitions, magnitude)
    return ScheduleValues(xi_large=xi_large, xi_small=xi_small, eps_x=eps_x_at(env_transitions, cartesian))
