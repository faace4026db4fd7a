"""HAMnet (paper Sec. method-modular-arch, with the authors' configuration where the paper
leaves it open): modulation network, module banks with gates, and the actor and critic
base networks; the student adds a GRU to each.

Modulation: robot and object state query the local and global scene tokens by
cross-attention; the object's [EMB] token, the two summaries and the context state
(`ObservationSpec.context`, previous action included) pass through an MLP (256, 256) to
the modulation embedding z_tau, from which one linear header predicts, for each of the L
base-network layers, a softmax over the M modules for the weights and another for the
biases, and per-unit gates 1 + linear(z_tau) on every hidden layer. Base: object state,
goal and hand query the object tokens; the summary and the base state feed the actor (mean
of a Gaussian over the raw action) and the critic (one value per reward term), each built
from its own module banks (`ModularMLP`). Shapes: B batch, N tokens, D token width,
L layers, M modules.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor, nn

from hamnet.policy.config import ModelConfig
from hamnet.policy.layers import MLP, CrossAttention, ModularMLP
from hamnet.policy.observation import NetworkInputs

GATE_INIT = 0.008
"""Gate header weights start U(-0.008, 0.008), biases 0 (init_std, hypernet_modular.py:281)."""


@dataclass(frozen=True)
class PolicyInputs:
    """One batch of everything a policy network may read."""

    observation: NetworkInputs
    object_tokens: Tensor | None
    """(B, N, D) UniCORN tokens of the object cloud, the last token is [EMB]; None for a
    network without clouds (`ModelConfig.clouds` False)."""
    local_tokens: Tensor | None = None
    """(B, N, D) tokens of the local (focal) scene cloud; None for the EnvCode oracle."""
    global_tokens: Tensor | None = None
    """(B, N, D) tokens of the global scene cloud; None for the EnvCode oracle."""
    env_code: Tensor | None = None
    """(B, 25) EnvCode, for the oracle ablation only."""
    memory: Tensor | None = None
    """(B, H) recurrent state of a student (zeros at an episode start); None otherwise."""


@dataclass(frozen=True)
class NetworkOutput:
    """What every architecture computes from `PolicyInputs`."""

    mean: Tensor
    """(B, A) mean of the Gaussian over raw actions."""
    values: Tensor
    """(B, R) value per reward term."""
    module_weights: Tensor
    """(B, L, M) module activations per base-network layer (actor layers, then critic)."""
    memory: Tensor | None
    """(B, H) next recurrent state, or None."""


def require(value: Tensor | None, what: str) -> Tensor:
    """`value`, or a ValueError naming the input this architecture is missing."""
    if value is None:
        raise ValueError(f"this architecture needs {what} in its inputs")
    return value


class ContextEncoder(nn.Module):
    """What tells a network its situation, (B, F): the local and global scene summaries
    (or the EnvCode), the object cloud's [EMB] token and the context state, in the
    authors' key_ctx order (rss_train.yaml:280-289; [EMB] is the last token, reduce "last",
    rss_train.yaml:324 and hypernet_modular.py:886-888)."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        spec = config.observation
        self.tokens = config.scene_input == "tokens"
        if self.tokens:
            args = (
                spec.width("scene_query"),
                config.token_dim,
                config.scene_attention_dim,
                config.scene_heads,
                config.attention_out,
                True,
            )
            self.local_attention = CrossAttention(*args)
            self.global_attention = CrossAttention(*args)
            scene = 2 * self.local_attention.width
        else:
            scene = config.env_code_dim
        self.width = config.token_dim + scene + spec.width("context")

    def forward(self, inputs: PolicyInputs) -> Tensor:
        """(B, F) context features."""
        query = inputs.observation.scene_query  # (B, Q1)
        if self.tokens:
            local = self.local_attention(query, require(inputs.local_tokens, "local tokens"))
            whole = self.global_attention(
                query, require(inputs.global_tokens, "global tokens"), repeated=True
            )
            scene = torch.cat((local, whole), dim=-1)  # (B, 2 E_out)
        else:
            scene = require(inputs.env_code, "the EnvCode")  # (B, 25)
        embedding = require(inputs.object_tokens, "object tokens")[:, -1]  # (B, D) [EMB]
        return torch.cat((embedding, scene, inputs.observation.context), dim=-1)


class ObjectEncoder(nn.Module):
    """Base-network input, (B, E_out + S): the object cross-attention summary (queried by
    object state, goal and hand, hypernet_modular.py:515-516, 983-991) and the base state."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        spec = config.observation
        self.attention = CrossAttention(
            spec.width("object_query"),
            config.token_dim,
            config.object_attention_dim,
            config.object_heads,
            config.attention_out,
            False,
        )
        self.width = self.attention.width + spec.width("base")

    def forward(self, inputs: PolicyInputs) -> Tensor:
        """(B, E_out + S) features."""
        summary = self.attention(
            inputs.observation.object_query, require(inputs.object_tokens, "object tokens")
        )
        return torch.cat((summary, inputs.observation.base), dim=-1)


class ModulationHeads(nn.Module):
    """One linear header from z_tau for one base network (one GEMM): the module logits of
    its weights and (when they have their own) its biases per layer, then the gates of its
    hidden layers' units. Its output layer has no gates (scale_last false,
    hypernet_modular.py:956-962)."""

    def __init__(self, z: int, base: ModularMLP, config: ModelConfig) -> None:
        super().__init__()
        self.num_layers, self.num_modules = len(base.layers), config.num_modules
        self.bias_weights = config.bias_weights
        self.gate_dims = list(base.out_dims[:-1]) if config.gates else []
        self.logits = self.num_layers * self.num_modules * (1 + config.bias_weights)
        self.linear = nn.Linear(z, self.logits + sum(self.gate_dims))
        with torch.no_grad():  # gates start near 1 (hypernet_modular.py:328-331)
            nn.init.uniform_(self.linear.weight[self.logits :], -GATE_INIT, GATE_INIT)
            self.linear.bias[self.logits :].zero_()

    def forward(self, z: Tensor) -> tuple[Tensor, Tensor, list[Tensor | None]]:
        """Module weights (B, L, M), bias module weights (B, L, M) and per-layer gates
        ((B, D_l) for hidden layers, None for the output layer and without gates)."""
        heads = self.linear(z)  # (B, L*M [+ L*M] + gates)
        # One softmax over every (layer, parameter) row of M logits; contiguous rows are
        # several times faster than the strided split.
        rows = heads[:, : self.logits].contiguous().view(len(z), -1, self.num_modules)
        softmax = torch.softmax(rows, dim=-1)
        weights = softmax[:, : self.num_layers]
        bias_weights = softmax[:, self.num_layers :] if self.bias_weights else weights
        if not self.gate_dims:
            return weights, bias_weights, [None] * self.num_layers
        gates = list(torch.split(1.0 + heads[:, self.logits :], self.gate_dims, dim=-1))
        return weights, bias_weights, [*gates, None]


class HAMNet(nn.Module):
    """The paper's policy (teacher), its no-gate and EnvCode ablations, and the student."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        self.config = config
        self.context = ContextEncoder(config)
        self.modulation = MLP((self.context.width, *config.modulation_hidden), activate_last=True)
        z = config.modulation_hidden[-1]
        self.object = ObjectEncoder(config)
        base_in = self.object.width
        if config.recurrent:
            self.modulation_gru = nn.GRUCell(z, z)
            self.base_gru = nn.GRUCell(base_in, config.base_memory)
            base_in += config.base_memory
        m = config.num_modules
        self.actor = ModularMLP((base_in, *config.base_hidden, config.action_dim), m)
        self.critic = ModularMLP((base_in, *config.base_hidden, config.num_values), m)
        # Each base network its own header, so the critic's rows are the critic's
        # parameters (`Policy.critic_parameters`: its own optimizer group and clip).
        self.actor_heads = ModulationHeads(z, self.actor, config)
        self.critic_heads = ModulationHeads(z, self.critic, config)

    @property
    def memory_width(self) -> int:
        """H of the recurrent state (0 for a feed-forward teacher)."""
        if not self.config.recurrent:
            return 0
        return self.config.modulation_hidden[-1] + self.config.base_memory

    def forward(self, inputs: PolicyInputs) -> NetworkOutput:
        """Mean (B, A), values (B, R), module weights (B, L, M) and the next memory."""
        x, z, memory = self._features(inputs)
        actor = self.actor_heads(z)
        mean = self.actor(x, *actor)
        if not self.config.shared_value_gradient and torch.is_grad_enabled():
            x, z = x.detach(), z.detach()  # the same features, their gradient stopped
        values, critic_weights = self._critic(x, z)
        weights = torch.cat((actor[0], critic_weights), dim=1)  # (B, L, M), actor's layers first
        return NetworkOutput(mean, values, weights, memory)

    def value_features(self, inputs: PolicyInputs) -> tuple[Tensor, Tensor]:
        """What the critic reads, (x (B, E + S [+ H]), z (B, Z)): everything before it, so
        PPO's critic-only steps, once the actor and the layers it shares are frozen, compute
        them once per update instead of once per step (`hamnet.trainer.algorithms.ppo`)."""
        x, z, _ = self._features(inputs)
        return x, z

    def values_from(self, features: tuple[Tensor, Tensor]) -> Tensor:
        """(B, R) values of `value_features`' output."""
        return self._critic(*features)[0]

    def _features(self, inputs: PolicyInputs) -> tuple[Tensor, Tensor, Tensor | None]:
        """The base networks' input x (B, E + S [+ H]), the modulation embedding z (B, Z) and
        the next memory (None for a feed-forward network)."""
        z = self.modulation(self.context(inputs))  # (B, Z)
        x = self.object(inputs)  # (B, E + S)
        if not self.config.recurrent:
            return x, z, None
        previous = require(inputs.memory, "the recurrent memory")  # (B, Z + H_base)
        z = self.modulation_gru(z, previous[:, : z.shape[1]])  # (B, Z)
        h = self.base_gru(x, previous[:, z.shape[1] :])  # (B, H_base)
        return torch.cat((x, h), dim=-1), z, torch.cat((z, h), dim=-1)

    def _critic(self, x: Tensor, z: Tensor) -> tuple[Tensor, Tensor]:
        """Values (B, R) and the critic's module weights (B, L, M)."""
        heads = self.critic_heads(z)
        return self.critic(x, *heads), heads[0]
