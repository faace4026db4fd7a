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
            args = (spec.width("scene_query"), config.token_dim, config.scene_attention_dim,
                    config.scene_heads, config.attention_out, True)  # fmt: skip
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
            whole = self.global_attention(query, require(inputs.global_tokens, "global tokens"))
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
            spec.width("object_query"), config.token_dim, config.object_attention_dim,
            config.object_heads, config.attention_out, False,
        )  # fmt: skip
        self.width = self.attention.width + spec.width("base")

    def forward(self, inputs: PolicyInputs) -> Tensor:
        """(B, E_out + S) features."""
        summary = self.attention(
            inputs.observation.object_query, require(inputs.object_tokens, "object tokens")
        )
        return torch.cat((summary, inputs.observation.base), dim=-1)


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
        self.num_layers = len(self.actor.layers) + len(self.critic.layers)
        # One linear layer for every header (one GEMM): module logits for the weights and
        # (when they have their own) the biases, then the gates of every hidden layer's
        # units. The output layers have no gates (scale_last false, hypernet_modular.py:
        # 956-962).
        logits, bias_logits = self.num_layers * m, self.num_layers * m * config.bias_weights
        hidden = self.actor.out_dims[:-1] + self.critic.out_dims[:-1]
        self.gate_dims = hidden if config.gates else []
        self.head_dims = [logits, bias_logits, sum(self.gate_dims)]
        self.heads = nn.Linear(z, sum(self.head_dims))
        with torch.no_grad():  # gates start near 1 (hypernet_modular.py:328-331)
            first_gate = logits + bias_logits
            nn.init.uniform_(self.heads.weight[first_gate:], -GATE_INIT, GATE_INIT)
            self.heads.bias[first_gate:].zero_()

    @property
    def memory_width(self) -> int:
        """H of the recurrent state (0 for a feed-forward teacher)."""
        if not self.config.recurrent:
            return 0
        return self.config.modulation_hidden[-1] + self.config.base_memory

    def forward(self, inputs: PolicyInputs) -> NetworkOutput:
        """Mean (B, A), values (B, R), module weights (B, L, M) and the next memory."""
        z = self.modulation(self.context(inputs))  # (B, Z)
        x = self.object(inputs)  # (B, E + S)
        memory = None
        if self.config.recurrent:
            previous = require(inputs.memory, "the recurrent memory")  # (B, Z + H_base)
            z = self.modulation_gru(z, previous[:, : z.shape[1]])  # (B, Z)
            h = self.base_gru(x, previous[:, z.shape[1] :])  # (B, H_base)
            memory, x = torch.cat((z, h), dim=-1), torch.cat((x, h), dim=-1)
        b, m = z.shape[0], self.config.num_modules
        heads = self.heads(z)  # (B, L*M [+ L*M] + gates)
        logits = self.head_dims[0] + self.head_dims[1]
        # One softmax over every (layer, parameter) row of M logits; contiguous rows are
        # several times faster than the strided split.
        softmax = torch.softmax(heads[:, :logits].contiguous().view(b, -1, m), dim=-1)
        weights = softmax[:, : self.num_layers]  # (B, L, M)
        bias_weights = softmax[:, self.num_layers :] if self.config.bias_weights else weights
        gate_logits = heads[:, logits:]
        gates = self._gates(gate_logits)
        la = len(self.actor.layers)
        mean = self.actor(x, weights[:, :la], bias_weights[:, :la], gates[:la])
        values = self.critic(x, weights[:, la:], bias_weights[:, la:], gates[la:])
        return NetworkOutput(mean, values, weights, memory)

    def _gates(self, logits: Tensor) -> list[Tensor | None]:
        """Per layer (actor's, then critic's): its gates (B, D_l), or None for the ungated
        output layers (and every layer without gates)."""
        la, lc = len(self.actor.layers), len(self.critic.layers)
        if not self.config.gates:
            return [None] * (la + lc)
        gates = list(torch.split(1.0 + logits, self.gate_dims, dim=-1))
        return gates[: la - 1] + [None] + gates[la - 1 :] + [None]
