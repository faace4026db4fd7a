"""PPO's loss terms and diagnostics, each a small function of flat minibatch tensors.

Shapes: N samples (time x environments, flattened), R reward terms, A action components.
Where a choice is the authors' rather than textbook PPO, the docstring cites it
(`ppo_util.py` is `ham/src/ham/models/rl/ppo_util.py` in iMSquared/HAMNet at 36f8267).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch
from torch import Tensor

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.safety.config import ActionMagnitudeConfig
from hamnet.safety.stages import affine_range


def row_moments(x: Tensor) -> tuple[Tensor, Tensor]:
    """Mean and biased variance of `x` over its rows (dim 0)."""
    return x.mean(dim=0), x.var(dim=0, unbiased=False)


def explained_variance(
    advantages: Tensor,
    returns: Tensor,
    moments: Callable[[Tensor], tuple[Tensor, Tensor]] = row_moments,
) -> float:
    """1 - Var(returns - values) / Var(returns) of the critic's summed value against the
    summed return targets (N, R) of a rollout, the values being the acting policy's: GAE's
    returns are advantages + values, so their difference is the advantages. 1: the critic
    predicts every target; 0: only their mean; below 0: worse than the mean (CleanRL's and
    Stable-Baselines3's diagnostic). The actor's advantages are as noisy as the critic is
    blind: near 0 they are the returns' own noise. NaN when the targets do not vary.
    `moments` as in `normalize_advantages`."""
    _, residual = moments(advantages.sum(dim=-1, keepdim=True))
    _, spread = moments(returns.sum(dim=-1, keepdim=True))
    return float(1.0 - residual / spread) if float(spread) > 0.0 else math.nan


def normalize_advantages(
    advantages: Tensor,
    eps: float = 1e-6,
    moments: Callable[[Tensor], tuple[Tensor, Tensor]] = row_moments,
) -> Tensor:
    """(N, R) advantages centred per term and divided by the standard deviation of their
    sum (assuming independent terms: the root of the summed variances), so the actor's
    summed advantage has unit scale and the terms keep their relative weights
    (`ppo_util.py`, `_ppo_loss_and_logs` with SUM_REW). `moments` gives the per-term mean
    and variance: of these rows, or of every learner rank's (`Ranks.moments`)."""
    mean, var = moments(advantages)
    centred = advantages - mean  # (N, R)
    return centred / (var.sum().sqrt() + eps)


def policy_loss(
    log_prob: Tensor, old_log_prob: Tensor, advantages: Tensor, clip: float, per_term: bool = False
) -> Tensor:
    """Clipped surrogate (PPO, Schulman et al. 2017, Eq. 7), negated for minimisation.

    Args:
        log_prob, old_log_prob: (N,) log-densities of the taken actions, now and when acting.
        advantages: (N, R) per reward term; the actor maximises their sum.
        clip: the ratio's clip range epsilon.
        per_term: clip each term's surrogate and sum them (the authors'); else clip the
            surrogate of the summed advantage (textbook PPO). The two agree for one term.
    """
    ratio = torch.exp(log_prob - old_log_prob)[:, None]  # (N, 1)
    if not per_term:
        advantages = advantages.sum(dim=1, keepdim=True)  # (N, 1)
    surrogate = torch.minimum(ratio * advantages, ratio.clamp(1 - clip, 1 + clip) * advantages)
    return -surrogate.sum(dim=1).mean()


def value_loss(values: Tensor, returns: Tensor) -> Tensor:
    """0.5 * squared error of every value head, (N, R) against its return, summed over heads
    and averaged over samples (`ppo_util.py`; value clipping is off: `clip_value: false`)."""
    return 0.5 * (values - returns).square().sum(dim=1).mean()


def bound_loss(mean: Tensor, low: Tensor, high: Tensor) -> Tensor:
    """Squared excess of the action mean (N, A) beyond [low, high] (A,), summed over
    components and averaged over samples: keeps the Gaussian's centre where actions still
    mean something (`ppo_util.py`, `BoundLoss`)."""
    above = (mean - high).clamp_min(0.0)
    below = (low - mean).clamp_min(0.0)
    return (above.square() + below.square()).sum(dim=1).mean()


def guide_loss(mean: Tensor, target: Tensor) -> Tensor:
    """Mean squared error of the action mean (N, A) against the guide's raw actions (N, A),
    over samples and components (`GuideConfig`); in float32 whatever the pass's precision."""
    return (mean.float() - target).square().mean()


def energy_loss(mean: Tensor, joint_velocity: Tensor, config: ActionMagnitudeConfig) -> Tensor:
    """Mean over samples of |tau * v|, the joint power of the impedance torque the action
    mean (N, A) asks for at the measured joint velocities v (N, J): tau = kp dq - kd v with
    dq, kp and kd = rho sqrt(kp) read from the mean as the safety filter reads an action
    (`hamnet.safety.stages.action_magnitude`, dq at xi_max) (`ppo_util.py`, `EnergyLoss`:
    the norm of tau * v over the joints)."""
    u = mean.clamp(-1.0, 1.0) if config.squash == "clip" else torch.tanh(mean)  # (N, A)
    xi_max = torch.full((NUM_JOINTS,), config.xi_max_small, dtype=mean.dtype)
    xi_max[: config.num_large_joints] = config.xi_max_large
    dq = xi_max * u[:, :NUM_JOINTS]
    kp = affine_range(u[:, NUM_JOINTS : 2 * NUM_JOINTS], config.kp_min, config.kp_max)
    rho = affine_range(u[:, 2 * NUM_JOINTS :], config.rho_min, config.rho_max)
    torque = kp * dq - rho * kp.sqrt() * joint_velocity
    return (torque * joint_velocity).norm(dim=1).mean()


def approx_kl(log_prob: Tensor, old_log_prob: Tensor) -> Tensor:
    """Estimate of KL(old || new) from (N,) log-densities of the old policy's samples:
    E[(r - 1) - log r], non-negative and unbiased (Schulman's k3)."""
    log_ratio = log_prob - old_log_prob
    return (torch.expm1(log_ratio) - log_ratio).mean()


def clip_fraction(log_prob: Tensor, old_log_prob: Tensor, clip: float) -> Tensor:
    """Share of samples whose ratio left [1 - clip, 1 + clip]."""
    return ((log_prob - old_log_prob).exp().sub(1.0).abs() > clip).float().mean()
