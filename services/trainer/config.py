"""PPO's hyperparameters, each with its source.

Rule (docs/mdp.md): where the paper's Table tab:PPO and the authors' training configuration
disagree, the configuration wins (it produced the reported numbers) and the paper's value is
kept as the `paper` preset. "config" below means the authors' repository (iMSquared/HAMNet
at 36f8267): `rss_train.yaml` is `ham/src/ham/data/cfg/rss_train.yaml`, `ppo_config.py` is
`ham/src/ham/models/rl/ppo_config.py` (its defaults apply where the YAML is silent) and
`ppo.py` is `ham/src/ham/models/rl/v6/ppo.py`.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PPOConfig:
    """One PPO update: advantages, losses, epochs, early stopping and the learning rate."""

    gamma: float = 0.99
    """Discount (paper Table tab:PPO; config `ppo_config.py:49`)."""
    gae_lambda: float = 0.95
    """GAE's lambda (paper; config `ppo_config.py:50`)."""
    clip: float = 0.3
    """PPO ratio clip range (paper; config `ppo_config.py:51`)."""
    epochs: int = 8
    """Most passes over a rollout per update (paper "Max Num. epoch"; `rss_train.yaml:179`)."""
    minibatches: int = 1
    """Gradient steps per epoch: the authors step once per epoch on the whole rollout
    (`accumulate_gradient: 1`, `rss_train.yaml:180`; `ppo.py:607-611`)."""
    lr: float = 3e-4
    """Base learning rate of Adam (paper; config `ppo_config.py:132`)."""
    kl_target: float = 0.016
    """Target of the KL-adaptive learning rate (paper; `rss_train.yaml:178`)."""
    kl_bounds: tuple[float, float] = (0.5, 2.0)
    """The rate grows below kl_bounds[0] * kl_target and shrinks above kl_bounds[1] *
    kl_target (config `ppo_config.py:88`, rule in `ham/src/ham/models/rl/adaptive_lr.py`)."""
    lr_factor: float = 1.5
    """Factor of each learning-rate change (config `ppo_config.py:89`)."""
    lr_bounds: tuple[float, float] = (1e-6, 1e-2)
    """The adapted learning rate stays in this range (config `ppo_config.py:90`)."""
    early_stop_factor: float = 1.5
    """An epoch stops (before its step) once the KL exceeds early_stop_factor * kl_target:
    0.024, the paper's "early-stopping KL target" (config `ppo.py:570-571`)."""
    policy_coef: float = 0.5
    """Weight of the clipped-surrogate loss: config `ppo_config.py:65` (the paper's table
    says 2; the two coefficients appear swapped there)."""
    value_coef: float = 2.0
    """Weight of the value loss, 0.5 * mean squared error (`rss_train.yaml:172`; paper 0.5)."""
    bound_coef: float = 0.02
    """Weight of the bound loss on the action mean (paper; `rss_train.yaml:171`)."""
    bound_scale: float = 1.1
    """The bound loss penalises a mean outside 1.1x the action bounds (config
    `ham/src/ham/models/rl/ppo_util.py`, `get_bound_loss(scale=1.1)`)."""
    energy_coef: float = 0.0
    """Weight of the energy loss (`losses.energy_loss`): 0, off, as the authors train
    (`use_energy_loss: False`, `ppo.py:101`); their coefficient when on is 5e-5
    (`ppo_config.py:69`), the paper's table says 8e-5."""
    normalize_advantages: bool = True
    """Advantages centred per term and scaled by the standard deviation of their sum
    (config `ppo_config.py:55`; `ppo_util.py` `_ppo_loss_and_logs`, `SUM_REW`)."""
    max_grad_norm: float = 1.0
    """Gradient clipping by global norm (config `ppo.py:98`)."""

    def __post_init__(self) -> None:
        for name in ("gamma", "gae_lambda"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if not self.energy_coef >= 0.0:
            raise ValueError(f"energy_coef must be >= 0, got {self.energy_coef}")
        for name in ("clip", "lr", "kl_target", "max_grad_norm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.epochs < 1 or self.minibatches < 1:
            raise ValueError("epochs and minibatches must be >= 1")
        if not self.lr_bounds[0] <= self.lr <= self.lr_bounds[1]:
            raise ValueError(f"lr {self.lr} outside lr_bounds {self.lr_bounds}")
        if not (0 < self.kl_bounds[0] < 1 < self.kl_bounds[1] and self.lr_factor > 1):
            raise ValueError("kl_bounds must straddle 1 and lr_factor must be > 1")


PPO_PRESETS: dict[str, PPOConfig] = {
    "code": PPOConfig(),
    "paper": PPOConfig(policy_coef=2.0, value_coef=0.5),
}
"""The authors' configuration (default) and the paper's Table tab:PPO where it differs."""
