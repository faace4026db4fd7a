"""The in-process policy core the service and the trainer share: a network plus the Gaussian
actor around it (PPO's act and evaluate) and the log-std schedule.

The observation is standardised by running statistics that are buffers too
(`normalizer.InputNormalizer`): the trainer updates them, the weights carry them.
The log std, the same for every state, is a parameter the PPO loss trains
(`LogStdConfig.mode` learned) or a buffer that follows `log_std_at(env_transitions)`
(schedule); either way it is saved with the weights, so the service samples with the
trainer's current std. Shapes: B batch, A action components, R reward terms,
L base-network layers, M modules, H recurrent memory.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import torch
from torch import Tensor, nn

from hamnet.policy.config import LogStdConfig, ModelConfig
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.normalizer import InputNormalizer

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


@dataclass(frozen=True)
class Action:
    """What `Policy.act` returns for one batch."""

    action: Tensor
    """(B, A) raw action (sample, or the mean when deterministic)."""
    log_prob: Tensor
    """(B,) log-density of `action` under the policy."""
    values: Tensor
    """(B, R) value per reward term."""
    module_weights: Tensor
    """(B, L, M) module activations."""
    memory: Tensor | None
    """(B, H) next recurrent state, or None."""


@dataclass(frozen=True)
class Evaluation:
    """What `Policy.evaluate` returns for given actions (the PPO losses' inputs)."""

    log_prob: Tensor
    """(B,) log-density of the given actions."""
    entropy: Tensor
    """(B,) entropy of the action distribution."""
    values: Tensor
    """(B, R) value per reward term."""
    memory: Tensor | None
    """(B, H) next recurrent state, or None."""
    mean: Tensor
    """(B, A) mean of the action distribution (PPO's bound loss keeps it in range)."""


def log_std_at(env_transitions: int, config: LogStdConfig) -> float:
    """log sigma after `env_transitions` (hamnet.runtime.counter) on the schedule: linear to
    `final` over a `horizon`, or one decay per started interval, as the authors decay after
    vectorized steps 0, 1024, 2048, ... (train.py:569)."""
    if config.horizon:
        done = min(env_transitions / config.horizon, 1.0)
        return config.initial + (config.final - config.initial) * done
    decays = -(-int(env_transitions) // config.interval)  # ceil
    return config.initial + config.decay * decays


class Policy(nn.Module):
    """A registered architecture's network with a diagonal Gaussian over raw actions."""

    def __init__(self, architecture: str, config: ModelConfig, network: nn.Module) -> None:
        super().__init__()
        self.architecture, self.config, self.network = architecture, config, network
        log_std = torch.full((config.action_dim,), config.log_std.initial)
        if config.log_std.mode == "learned":
            self.log_std = nn.Parameter(log_std)
        else:
            self.register_buffer("log_std", log_std)
        self.normalizer = InputNormalizer(config.observation)
        """Running statistics of the observation groups, saved with the weights."""

    @property
    def memory_width(self) -> int:
        """H of the recurrent memory; 0 for feed-forward networks."""
        return getattr(self.network, "memory_width", 0)

    def initial_memory(self, batch: int) -> Tensor | None:
        """(B, H) zeros for a recurrent policy at episode starts; None otherwise."""
        if not self.memory_width:
            return None
        return self.log_std.new_zeros(batch, self.memory_width)

    def set_env_transitions(self, env_transitions: int) -> None:
        """Move a scheduled log std to its value at the trainer's counter (a learned one
        stays where training put it)."""
        if self.config.log_std.mode == "schedule":
            self.log_std.fill_(log_std_at(env_transitions, self.config.log_std))

    def critic_parameters(self) -> list[nn.Parameter]:
        """Parameters only the value loss reaches (the network's `critic`, and HAMnet's
        `critic_heads`): the optimizer may step them at their own rate and clip their
        gradient on its own (`hamnet.trainer.algorithms.ppo`)."""
        heads = getattr(self.network, "critic_heads", None)
        own = list(heads.parameters()) if heads is not None else []
        return list(self.network.critic.parameters()) + own

    def actor_parameters(self) -> list[nn.Parameter]:
        """Every other parameter: the actor's, the log std and what both heads share."""
        critic = {id(p) for p in self.critic_parameters()}
        return [p for p in self.parameters() if id(p) not in critic]

    def act(
        self,
        inputs: PolicyInputs,
        deterministic: bool = False,
        generator: torch.Generator | None = None,
    ) -> Action:
        """Actions for one batch: a sample (or the mean), its log-prob, values, modules."""
        out = self.network(self._standardised(inputs))
        std = self.log_std.exp().expand_as(out.mean)  # (B, A)
        if deterministic:
            action = out.mean
        else:
            noise = torch.randn(out.mean.shape, generator=generator, device=out.mean.device)
            action = out.mean + std * noise  # (B, A)
        log_prob = self._log_prob(action, out.mean)
        return Action(action, log_prob, out.values, out.module_weights, out.memory)

    def evaluate(self, inputs: PolicyInputs, actions: Tensor) -> Evaluation:
        """Log-prob and entropy of `actions` (B, A) and the values, with gradients. Under
        autocast (a bfloat16 update) only the network runs in low precision: the mean and
        values come back as float32, and the log-probabilities are computed from them."""
        out = self.network(self._standardised(inputs))
        mean, values = out.mean.float(), out.values.float()
        entropy = (self.log_std + 0.5 + _LOG_SQRT_2PI).sum().expand(actions.shape[0])  # (B,)
        return Evaluation(self._log_prob(actions, mean), entropy, values, out.memory, mean)

    @property
    def reads_value_features(self) -> bool:
        """Whether the network splits its critic from what it reads (`value_features`,
        `values_from`), so PPO's critic-only steps can skip everything before it."""
        return hasattr(self.network, "value_features")

    def value_features(self, inputs: PolicyInputs) -> Any:
        """What the network's critic reads of these inputs (a tree of (B, ...) tensors)."""
        return self.network.value_features(self._standardised(inputs))

    def values_from(self, features: Any) -> Tensor:
        """(B, R) values of `value_features`' output, with gradients for the critic (float32,
        under autocast too)."""
        return self.network.values_from(features).float()

    def _standardised(self, inputs: PolicyInputs) -> PolicyInputs:
        """`inputs` with the observation standardised by the running statistics."""
        return dataclasses.replace(inputs, observation=self.normalizer(inputs.observation))

    def _log_prob(self, action: Tensor, mean: Tensor) -> Tensor:
        """(B,) log N(action; mean, exp(log_std)^2), summed over the A components."""
        z = (action - mean) * torch.exp(-self.log_std)
        return (-0.5 * z.square() - self.log_std - _LOG_SQRT_2PI).sum(dim=-1)

    def parameter_count(self) -> int:
        """Trainable parameters (a learned log std among them)."""
        return sum(p.numel() for p in self.parameters())
