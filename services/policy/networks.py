"""HAMnet (paper Sec. method-modular-arch): modulation network, module banks with gates,
and the actor and critic base networks; the student adds a GRU to each.

Modulation: the robot and object state (group 1) query the local and global scene tokens
by cross-attention; the two summaries, the object's [EMB] token and the full state
(group 3) pass through an MLP (256, 256) to the modulation embedding z_tau, from which two
heads predict, for each of the L base-network layers, a softmax over the M modules and
per-unit gates 1 + linear(z_tau). Base: the hand and goal (group 2) query the object
tokens; the summary and the state feed the actor (mean of a Gaussian over the 21 raw
action components) and the critic (one value per reward term), each built from its own
module banks (`ModularMLP`). Shapes: B batch, N tokens, D token width, L layers, M modules.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor, nn

from hamnet.policy.config import ModelConfig
from hamnet.policy.layers import MLP, CrossAttention, ModularMLP
from hamnet.policy.observation import Observation, widths


@dataclass(frozen=True)
class PolicyInputs:
    """One batch of everything a policy network may read."""

    observation: Observation
    object_tokens: Tensor
    """(B, N, D) UniCORN tokens of the object cloud; token 0 is [EMB]."""
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


def _require(value: Tensor | None, what: str) -> Tensor:
    if value is None:
        raise ValueError(f"this architecture needs {what} in its inputs")
    return value


class ContextEncoder(nn.Module):
    """What tells a network its situation: scene summary + object [EMB] + state, (B, F).

    F = 2E (local and global cross-attention summaries) or 25 (EnvCode) + D + S."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        state, scene_query, _ = widths(config.privileged)
        self.tokens = config.scene_input == "tokens"
        if self.tokens:
            args = (scene_query, config.token_dim, config.attention_dim, config.scene_heads)
            self.local_attention = CrossAttention(*args)
            self.global_attention = CrossAttention(*args)
            scene = 2 * config.attention_dim
        else:
            scene = config.env_code_dim
        self.width = scene + config.token_dim + state

    def forward(self, inputs: PolicyInputs) -> Tensor:
        """(B, F) context features."""
        query = inputs.observation.scene_query  # (B, Q1)
        if self.tokens:
            local = self.local_attention(query, _require(inputs.local_tokens, "local tokens"))
            whole = self.global_attention(query, _require(inputs.global_tokens, "global tokens"))
            scene = torch.cat((local, whole), dim=-1)  # (B, E + E)
        else:
            scene = _require(inputs.env_code, "the EnvCode")  # (B, 25)
        embedding = inputs.object_tokens[:, 0]  # (B, D) [EMB]
        return torch.cat((scene, embedding, inputs.observation.state), dim=-1)


class ObjectEncoder(nn.Module):
    """Base-network input: object cross-attention summary + state, (B, E + S)."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        state, _, object_query = widths(config.privileged)
        self.attention = CrossAttention(
            object_query, config.token_dim, config.attention_dim, config.object_heads
        )
        self.width = config.attention_dim + state

    def forward(self, inputs: PolicyInputs) -> Tensor:
        """(B, E + S) features."""
        summary = self.attention(inputs.observation.object_query, inputs.object_tokens)  # (B, E)
        return torch.cat((summary, inputs.observation.state), dim=-1)


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
        # One linear layer for every header (one GEMM): module logits for the weights,
        # for the biases (when they have their own), and the gates of every layer's units.
        logits = self.num_layers * m
        self.gate_dims = self.actor.out_dims + self.critic.out_dims if config.gates else []
        self.head_dims = [logits, logits if config.bias_weights else 0, sum(self.gate_dims)]
        self.heads = nn.Linear(z, sum(self.head_dims))
        with torch.no_grad():  # gates start near 1: the modules alone decide at first
            first_gate = logits + self.head_dims[1]
            self.heads.weight[first_gate:].mul_(0.01)
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
            previous = _require(inputs.memory, "the recurrent memory")  # (B, Z + H_base)
            z = self.modulation_gru(z, previous[:, : z.shape[1]])  # (B, Z)
            h = self.base_gru(x, previous[:, z.shape[1] :])  # (B, H_base)
            memory, x = torch.cat((z, h), dim=-1), torch.cat((x, h), dim=-1)
        b, m = z.shape[0], self.config.num_modules
        weight_logits, bias_logits, gate_logits = torch.split(self.heads(z), self.head_dims, -1)
        weights = torch.softmax(weight_logits.view(b, self.num_layers, m), dim=-1)  # (B, L, M)
        bias_weights = weights
        if self.config.bias_weights:
            bias_weights = torch.softmax(bias_logits.view(b, self.num_layers, m), dim=-1)
        gates = None
        if self.config.gates:
            gates = torch.split(1.0 + gate_logits, self.gate_dims, dim=-1)  # L x (B, D_l)
        la = len(self.actor.layers)
        mean = self.actor(x, weights[:, :la], bias_weights[:, :la], gates and gates[:la])
        values = self.critic(x, weights[:, la:], bias_weights[:, la:], gates and gates[la:])
        return NetworkOutput(mean, values, weights, memory)
