"""Running statistics for observation normalization and return-based reward scaling.

Observations are standardised with running means and variances (the authors'
`NormalizeEnv`, `ham/src/ham/env/env/wrap/normalize_env.py`; inputs that already have
fixed scales, such as UniCORN tokens, are left out by the caller as the authors' `constlist`
does, `rss_train.yaml:496-510`). Rewards are divided by the running standard deviation of
the discounted return of their sum (`sum_rew: True` in `NormalizeEnv.Config`), one scalar
for all terms, so the reward terms keep their relative weights. State is plain tensors, so
checkpoints store it as safetensors.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from hamnet.policy.normalizer import merge_moments


class RunningMeanStd:
    """Mean and variance of a stream of (N, *shape) batches (`merge_moments`)."""

    def __init__(self, shape: tuple[int, ...], eps: float = 1e-6) -> None:
        self.mean = torch.zeros(shape, dtype=torch.float64)
        self.var = torch.ones(shape, dtype=torch.float64)
        self.count = torch.tensor(eps, dtype=torch.float64)
        """Samples seen; starts at eps so the first batch takes over the prior."""

    def update(self, batch: Tensor) -> None:
        """Fold (N, *shape) samples into the statistics."""
        if len(batch):
            self.mean, self.var, self.count = merge_moments(self.mean, self.var, self.count, batch)

    def normalize(self, x: Tensor, eps: float = 1e-6) -> Tensor:
        """(..., *shape) standardised, in x's dtype."""
        mean, std = self.mean.to(x.dtype), self.var.sqrt().to(x.dtype)
        return (x - mean) / (std + eps)

    def state(self, prefix: str) -> dict[str, Tensor]:
        """Tensors to checkpoint, under `prefix`."""
        return {
            f"{prefix}.mean": self.mean,
            f"{prefix}.var": self.var,
            f"{prefix}.count": self.count,
        }

    def load(self, tensors: dict[str, Tensor], prefix: str) -> None:
        """Restore what `state(prefix)` saved."""
        self.mean, self.var = tensors[f"{prefix}.mean"].clone(), tensors[f"{prefix}.var"].clone()
        self.count = tensors[f"{prefix}.count"].clone()


class ReturnScaler:
    """Divides rewards by the running std of the discounted return of their sum."""

    def __init__(self, num_envs: int, gamma: float, eps: float = 1e-6) -> None:
        self.gamma, self.eps = gamma, eps
        self.returns = torch.zeros(num_envs, dtype=torch.float64)
        """(B,) discounted return of the summed reward so far in each episode."""
        self.stats = RunningMeanStd(())

    def snapshot(self) -> tuple[dict[str, Tensor], dict[str, float]]:
        """The running returns and statistics, to continue from with `restore`."""
        return {"returns": self.returns, **self.stats.state("stats")}, {}

    def restore(self, arrays: dict[str, np.ndarray], meta: dict[str, float]) -> None:
        """Continue from `snapshot`'s arrays (copied into torch-allocated tensors).

        Raises:
            ValueError: the snapshot scaled another number of environments.
        """
        if arrays["returns"].shape != tuple(self.returns.shape):
            raise ValueError(
                f"the snapshot scaled {len(arrays['returns'])} environments, "
                f"this run has {len(self.returns)}"
            )
        self.returns = torch.tensor(arrays["returns"])
        self.stats.load({name: torch.tensor(a) for name, a in arrays.items()}, "stats")

    def scale(self, rewards: Tensor, dones: Tensor, envs: Tensor | None = None) -> Tensor:
        """Scaled (B, R) rewards of one step of the environments `envs` (B,) (None: all, in
        order); `dones` (B,) ends the episodes after it.

        The statistics see the return including this step, then episodes that ended
        restart from zero (the authors' order, `normalize_env.py` `step`).
        """
        returns = self.returns if envs is None else self.returns[envs]  # (B,)
        returns = returns * self.gamma + rewards.sum(dim=1).to(torch.float64)
        self.stats.update(returns)
        returns = torch.where(dones.bool(), torch.zeros_like(returns), returns)
        if envs is None:
            self.returns = returns
        else:
            self.returns[envs] = returns
        return rewards / (self.stats.var.sqrt().to(rewards.dtype) + self.eps)
