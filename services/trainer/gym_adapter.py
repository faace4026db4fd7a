"""hamnet's PPO core on a Gymnasium vector environment, so it can be checked against an
outside PPO on a standard task (issue 27; `benchmarks/ppo_reference.py`, docs/trainer.md
"Checked against an outside PPO").

It consumes any environment with Gymnasium's vector API in `SAME_STEP` autoreset mode (an
ended episode's last observation in `info["final_obs"]`, the next episode's first one
returned in its place) and learns with the trainer's own pieces in the trainer's order
(`Runner.learn`): rewards scaled by `ReturnScaler`, then + gamma * V(final observation) of
truncated episodes, `gae` with one reward term (R = 1), `Batch` and `ppo.update`;
observations standardised by `RunningMeanStd`, which takes in each rollout after its update,
the first rollout filling the statistics without an update (`Runner.iterate`). The
actor-critic is the reference's (Stable-Baselines3's `MlpPolicy`),
so a gap points at the core, not the network. Nothing here imports gymnasium: hamnet runs
without it. Shapes: T steps, B environments, O observation, A action.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import torch
from torch import Tensor, nn

from hamnet.policy.init import initialize
from hamnet.trainer.algorithms.gae import gae
from hamnet.trainer.algorithms.normalization import ReturnScaler, RunningMeanStd
from hamnet.trainer.algorithms.ppo import Batch, UpdateStats, optimizer_for, update
from hamnet.trainer.config import PPOConfig

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)
OBS_CLIP = 5.0
"""Standardised observations are clipped to +-5, as the trainer's `InputNormalizer` clips
(`hamnet.policy.normalizer`; SB3's `VecNormalize` clips at 10)."""


class VectorEnv(Protocol):
    """What the adapter uses of a `gymnasium.vector.VectorEnv` in SAME_STEP autoreset mode."""

    num_envs: int
    single_observation_space: Any
    single_action_space: Any
    """A Box: its `low` and `high` (A,) bound the actions sent and the bound loss."""

    def reset(self, *, seed: int | None = None) -> tuple[np.ndarray, dict]: ...

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]: ...


STANDARD_PPO = PPOConfig(
    clip=0.2,
    epochs=10,
    minibatches=32,
    kl_stop="off",
    lr_schedule="fixed",
    value_lr=None,
    policy_coef=1.0,
    value_coef=1.0,
    max_grad_norm=0.5,
)
"""PPO as Schulman et al. 2017 ran it on MuJoCo and Stable-Baselines3 defaults to: clip 0.2
(Sec. 6.1), 10 epochs of minibatches of 64 (Table 3; 32 minibatches of a 2048-step
rollout), Adam at a fixed 3e-4, gamma 0.99, lambda 0.95 (the `PPOConfig` defaults), no KL
stop (SB3's `target_kl=None`), one optimizer for actor and critic, loss = policy + 0.5 MSE
(SB3's `vf_coef` 0.5 on its MSE is `value_coef` 1 on our 0.5 x squared error), gradient
norm 0.5. The bound loss stays at ours (0.02 beyond 1.1x the bounds): SB3 has none."""


@dataclass(frozen=True)
class GymPPOConfig:
    """The adapter's run: rollout length, network and the PPO update's settings."""

    steps_per_rollout: int = 2048
    """T per environment between updates (SB3's `n_steps` default, Schulman et al. 2017
    Table 3's horizon)."""
    hidden: tuple[int, ...] = (64, 64)
    """Hidden widths of the actor and of the critic (SB3's `MlpPolicy` default)."""
    log_std_init: float = 0.0
    """Initial log std of the Gaussian, learned from there (SB3's default)."""
    ppo: PPOConfig = field(default_factory=lambda: STANDARD_PPO)

    def __post_init__(self) -> None:
        if self.steps_per_rollout < 1:
            raise ValueError(f"steps_per_rollout must be >= 1, got {self.steps_per_rollout}")


@dataclass(frozen=True)
class Acted:
    """The policy's action for one step of B environments."""

    action: Tensor
    """(B, A) sample of the Gaussian, before clipping to the action space."""
    log_prob: Tensor
    """(B,) its log-density."""
    values: Tensor
    """(B, 1) V(s)."""


@dataclass(frozen=True)
class Evaluation:
    """Given actions under the current parameters, with gradients (`ppo.Evaluated`)."""

    log_prob: Tensor
    """(N,)"""
    values: Tensor
    """(N, 1)"""
    mean: Tensor
    """(N, A)"""


def gaussian_log_prob(action: Tensor, mean: Tensor, log_std: Tensor) -> Tensor:
    """(N,) log N(action; mean, exp(log_std)^2) of (N, A) actions, summed over A (the
    trainer's `Policy._log_prob`, with log_std a parameter here)."""
    z = (action - mean) * torch.exp(-log_std)
    return (-0.5 * z.square() - log_std - _LOG_SQRT_2PI).sum(dim=-1)


def tanh_mlp(dims: list[int]) -> nn.Sequential:
    """Linear -> tanh between layers, the last layer linear."""
    layers: list[nn.Module] = []
    for i, o in itertools.pairwise(dims[:-1]):
        layers += [nn.Linear(i, o), nn.Tanh()]
    return nn.Sequential(*layers, nn.Linear(dims[-2], dims[-1]))


class ActorCritic(nn.Module):
    """Separate actor and critic MLPs on standardised observations and a learned,
    state-independent log std: SB3's `MlpPolicy`, with the trainer's orthogonal
    initialization (`hamnet.policy.init`: gain sqrt(2), actor output 0.01, critic output 1,
    the same as SB3's `ortho_init`).

    Not `hamnet.policy.layers.MLP`: its LayerNorm between layers is not in the reference's
    network, and the comparison is of the PPO core.
    """

    def __init__(self, obs_dim: int, action_dim: int, config: GymPPOConfig) -> None:
        super().__init__()
        hidden = list(config.hidden)
        self.actor = tanh_mlp([obs_dim, *hidden, action_dim])
        self.critic = tanh_mlp([obs_dim, *hidden, 1])
        initialize(self)
        self.log_std = nn.Parameter(torch.full((action_dim,), config.log_std_init))
        self.observations = RunningMeanStd((obs_dim,))
        """Observation statistics, updated by the learner after each iteration."""

    def actor_parameters(self) -> list[Tensor]:
        """What the policy loss reaches: the actor and the log std."""
        return [*self.actor.parameters(), self.log_std]

    def standardise(self, obs: Tensor) -> Tensor:
        """(N, O) raw observations standardised and clipped to +-OBS_CLIP; zeros before any
        statistics, as the trainer's `InputNormalizer` reads an input of unknown mean."""
        if self.observations.count < 1:
            return torch.zeros_like(obs)
        return self.observations.normalize(obs).clamp(-OBS_CLIP, OBS_CLIP)

    @torch.no_grad()
    def act(self, obs: Tensor, generator: torch.Generator | None = None) -> Acted:
        """A Gaussian sample for raw observations (B, O)."""
        x = self.standardise(obs)
        mean = self.actor(x)  # (B, A)
        noise = torch.randn(mean.shape, generator=generator)
        action = mean + self.log_std.exp() * noise
        return Acted(action, gaussian_log_prob(action, mean, self.log_std), self.critic(x))

    @torch.no_grad()
    def value(self, obs: Tensor) -> Tensor:
        """(B, 1) V of raw observations (B, O)."""
        return self.critic(self.standardise(obs))

    def evaluate(self, obs: Tensor, actions: Tensor) -> Evaluation:
        """Log-density of (N, A) actions, values and means for raw observations (N, O)."""
        x = self.standardise(obs)
        mean = self.actor(x)
        return Evaluation(gaussian_log_prob(actions, mean, self.log_std), self.critic(x), mean)


@dataclass(frozen=True)
class GymRollout:
    """T steps of B environments, time-major, with one reward term."""

    observations: Tensor
    """(T, B, O) raw observations acted on."""
    actions: Tensor
    """(T, B, A) Gaussian samples, before clipping to the action space."""
    log_prob: Tensor
    """(T, B)"""
    values: Tensor
    """(T, B, 1) V of the observations acted on."""
    rewards: Tensor
    """(T, B, 1) as the environment gave them."""
    final_values: Tensor
    """(T, B, 1) V(final observation) where an episode was truncated (not terminated) at t."""
    dones: Tensor
    """(T, B) bool: the episode ended at t, terminated or truncated."""
    next_values: Tensor
    """(B, 1) V of the observations after the last step."""


class GymPPO:
    """The learner: an `ActorCritic`, its optimizer, the return scaler and the envs' state."""

    def __init__(self, env: VectorEnv, config: GymPPOConfig, seed: int) -> None:
        self.env, self.config = env, config
        space = env.single_action_space
        self.low, self.high = np.asarray(space.low), np.asarray(space.high)
        obs_dim = int(np.prod(env.single_observation_space.shape))
        with torch.random.fork_rng(devices=[]):  # seeded weights, the caller's RNG untouched
            torch.manual_seed(seed)
            self.model = ActorCritic(obs_dim, len(self.low), config)
        self.optimizer = optimizer_for(
            self.model.actor_parameters(), self.model.critic.parameters(), config.ppo
        )
        self.scaler = ReturnScaler(env.num_envs, config.ppo.gamma)
        self.generator = torch.Generator().manual_seed(seed)
        """Of the action noise and the minibatches."""
        self.obs = _tensor(env.reset(seed=seed)[0])  # (B, O)
        self.env_steps = 0
        self.running = np.zeros(env.num_envs)
        """(B,) undiscounted return of each current episode so far."""
        self.episodes: list[tuple[int, float]] = []
        """(env steps when it ended, undiscounted return) of every finished episode."""

    def train(
        self, env_steps: int, on_update: Callable[[dict[str, float]], None] | None = None
    ) -> None:
        """Iterate until `env_steps` transitions are spent; `on_update` sees every update's
        figures."""
        while self.env_steps < env_steps:
            row = self.iterate()
            if row and on_update is not None:
                on_update(row)

    def iterate(self) -> dict[str, float]:
        """One rollout and one update, then the observation statistics take in the rollout
        (acting and evaluating saw the same). The first rollout, acted on zeroed inputs, only
        fills the statistics and the return scaler, so every action learned from saw
        standardised inputs (the trainer's `Runner.iterate`); it returns no figures."""
        rollout = self.collect()
        row: dict[str, float] = {}
        if self.model.observations.count < 1:
            for rewards, dones in zip(rollout.rewards, rollout.dones):
                self.scaler.scale(rewards, dones)
        else:
            row = {"env_steps": self.env_steps, **self.learn(rollout)}
        self.model.observations.update(
            rollout.observations.reshape(-1, rollout.observations.shape[-1])
        )
        return row

    @torch.no_grad()
    def collect(self) -> GymRollout:
        """`steps_per_rollout` steps of every environment with the current policy."""
        records: list[dict[str, Tensor]] = []
        for _ in range(self.config.steps_per_rollout):
            obs = self.obs
            acted = self.model.act(obs, self.generator)
            rewards, dones, final_values = self._step(acted.action.numpy())
            records.append(
                {
                    "observations": obs,
                    "actions": acted.action,
                    "log_prob": acted.log_prob,
                    "values": acted.values,
                    "rewards": rewards,
                    "final_values": final_values,
                    "dones": dones,
                }
            )
        fields = {key: torch.stack([r[key] for r in records]) for key in records[0]}
        return GymRollout(**fields, next_values=self.model.value(self.obs))

    def learn(self, rollout: GymRollout) -> dict[str, float]:
        """The trainer's `learn` on one term: scale, bootstrap, GAE, update. Returns the
        update's figures, the explained variance of the values acted with and the log std."""
        ppo = self.config.ppo
        advantages, returns = self.targets(rollout)
        flat = lambda x: x.reshape(-1, *x.shape[2:])  # (T, B, ...) -> (T * B, ...)
        batch = Batch(
            flat(rollout.observations),
            flat(rollout.actions),
            flat(rollout.log_prob),
            flat(advantages),
            flat(returns),
        )
        bounds = (torch.as_tensor(self.low), torch.as_tensor(self.high))
        stats = update(
            self.model.evaluate,
            self.model.parameters(),
            self.optimizer,
            batch,
            bounds,
            ppo,
            self.generator,
        )
        return {
            **_figures(stats),
            "explained_variance": explained_variance(rollout.values, returns),
            "log_std": float(self.model.log_std.detach().mean()),
        }

    def targets(self, rollout: GymRollout) -> tuple[Tensor, Tensor]:
        """(T, B, 1) advantages and returns: rewards scaled by the running std of the
        discounted return, + gamma V(final observation) where truncated, GAE."""
        ppo = self.config.ppo
        scaled = torch.stack(
            [self.scaler.scale(r, d) for r, d in zip(rollout.rewards, rollout.dones)]
        )
        rewards = scaled + ppo.gamma * rollout.final_values  # (T, B, 1)
        return gae(
            rewards, rollout.values, rollout.next_values, rollout.dones, ppo.gamma, ppo.gae_lambda
        )

    def _step(self, actions: np.ndarray) -> tuple[Tensor, Tensor, Tensor]:
        """Step every environment with (B, A) actions clipped to the action space (as SB3
        does); returns (B, 1) rewards, (B,) dones and (B, 1) V(final observation) of the
        truncated episodes (0 elsewhere), and records finished episodes."""
        obs, reward, terminated, truncated, info = self.env.step(
            np.clip(actions, self.low, self.high)
        )
        self.env_steps += self.env.num_envs
        self.running += reward
        dones = np.logical_or(terminated, truncated)
        final_values = torch.zeros(len(dones), 1)
        timed_out = np.flatnonzero(truncated & ~terminated)
        if len(timed_out):
            final = np.stack([info["final_obs"][i] for i in timed_out])  # (K, O)
            final_values[timed_out] = self.model.value(_tensor(final))
        for i in np.flatnonzero(dones):
            self.episodes.append((self.env_steps, float(self.running[i])))
            self.running[i] = 0.0
        self.obs = _tensor(obs)
        return _tensor(reward)[:, None], torch.as_tensor(dones), final_values


def explained_variance(values: Tensor, returns: Tensor) -> float:
    """1 - Var(returns - values) / Var(returns): the share of the value targets' variance
    the critic predicted (1 perfect, 0 no better than their mean)."""
    var = returns.var()
    return float(1.0 - (returns - values).var() / var) if var > 0 else math.nan


def _figures(stats: UpdateStats) -> dict[str, float]:
    """An update's figures for a log row."""
    return {
        "approx_kl": stats.approx_kl,
        "clip_fraction": stats.clip_fraction,
        "value_loss": stats.value_loss,
        "policy_loss": stats.policy_loss,
        "bound_loss": stats.bound_loss,
        "gradient_steps": stats.gradient_steps,
        "gradient_agreement": stats.gradient_agreement,
        "explained_variance": stats.explained_variance,
    }


def _tensor(x: np.ndarray) -> Tensor:
    """float32 tensor of an array."""
    return torch.as_tensor(np.asarray(x), dtype=torch.float32)
