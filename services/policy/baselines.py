"""The paper's baseline architectures (Sec. baseline-arch), on the same inputs as HAMnet,
and a state-only MLP (`StateMLP`), the plain PPO baseline of the learning result.

- `MonolithicMLP` (UniCORN-MONO): the same cross-attentions, every summary concatenated
  with the state, actor and critic MLPs sized to match HAMnet's parameter count (the paper's
  768-384-384-192, scaled; see `ModelConfig.mlp_hidden`).
- `HyperNetwork` (UniCORN-HYPER): an MLP (256, 256) on the context predicts, per layer,
  low-rank factors W = W_l W_r (rank 16) and the bias; W x is computed as W_l (W_r x).
- `SoftModularization` (UniCORN-SM, Yang et al. 2020): M modules per layer with the base
  network's widths; a routing network predicts, layer after layer and conditioned on the
  previous layer's routing, the M x M connection weights between modules of neighbouring
  layers; module routings are embedded with 128 dims and mapped by two-layer MLPs (128).

Shapes: B batch, M modules, J in, I out, k rank.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import torch
from torch import Tensor, nn

from hamnet.policy.config import ModelConfig
from hamnet.policy.layers import MLP, hidden_activation
from hamnet.policy.networks import (
    ContextEncoder,
    NetworkOutput,
    ObjectEncoder,
    PolicyInputs,
    require,
)


def _no_modules(batch: int, like: Tensor) -> Tensor:
    """(B, 0, 1): a network without modules reports no module activations."""
    return like.new_zeros(batch, 0, 1)


def _feed_forward(config: ModelConfig, name: str) -> None:
    if config.recurrent:
        raise ValueError(f"{name} has no recurrent variant; the student is HAMnet's")


class MonolithicMLP(nn.Module):
    """UniCORN-MONO: the cross-attention summaries and the state into wide MLPs."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        _feed_forward(config, "mlp")
        self.context, self.object = ContextEncoder(config), ObjectEncoder(config)
        width = self.context.width + self.object.attention.width  # the state enters once
        self.actor = MLP((width, *config.mlp_hidden, config.action_dim))
        self.critic = MLP((width, *config.mlp_hidden, config.num_values))

    def forward(self, inputs: PolicyInputs) -> NetworkOutput:
        """Mean (B, A), values (B, R); no module weights (B, 0, 1)."""
        summary = self.object.attention(
            inputs.observation.object_query, require(inputs.object_tokens, "object tokens")
        )
        x = torch.cat((self.context(inputs), summary), dim=-1)  # (B, F + E)
        mean = self.actor(x)
        return NetworkOutput(mean, self.critic(x), _no_modules(len(x), x), None)


class StateMLP(nn.Module):
    """A plain state-based baseline: MLPs (256, 256) over the privileged state alone (the
    context group: robot, object and goal state, previous action, physics parameters), no
    clouds. What a new user tries first; the learning result compares HAMnet against it."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        _feed_forward(config, "state-mlp")
        if config.clouds or not config.privileged:
            raise ValueError("state-mlp reads the privileged state and no clouds (clouds=False)")
        width = config.observation.width("context")
        self.actor = MLP((width, *config.state_hidden, config.action_dim))
        self.critic = MLP((width, *config.state_hidden, config.num_values))

    def forward(self, inputs: PolicyInputs) -> NetworkOutput:
        """Mean (B, A), values (B, R); no module weights (B, 0, 1)."""
        x = inputs.observation.context  # (B, F)
        return NetworkOutput(self.actor(x), self.critic(x), _no_modules(len(x), x), None)


class LowRankBase(nn.Module):
    """One base network (actor or critic) whose parameters a hypernetwork head predicts."""

    def __init__(self, dims: Sequence[int], rank: int, embedding: int) -> None:
        super().__init__()
        self.dims, self.rank = tuple(dims), rank
        self.sizes = [(i + j) * rank + i for j, i in itertools.pairwise(dims)]  # W_l, W_r, b
        self.head = nn.Linear(embedding, sum(self.sizes))

    def forward(self, x: Tensor, z: Tensor) -> Tensor:
        """(B, J) through the layers generated from z (B, Z) -> (B, out)."""
        b, k = x.shape[0], self.rank
        chunks = torch.split(self.head(z), self.sizes, dim=-1)
        last = len(chunks) - 1
        for index, (chunk, j, i) in enumerate(zip(chunks, self.dims[:-1], self.dims[1:])):
            left = chunk[:, : i * k].view(b, i, k) / math.sqrt(k)  # (B, I, k) W_l
            right = chunk[:, i * k : (i + j) * k].view(b, k, j) / math.sqrt(j)  # (B, k, J) W_r
            bias = chunk[:, (i + j) * k :]  # (B, I)
            x = (left @ (right @ x.unsqueeze(2))).squeeze(2) + bias  # (B, I), W never built
            if index < last:
                x = hidden_activation(x)
        return x


class HyperNetwork(nn.Module):
    """UniCORN-HYPER: the base networks' low-rank parameters predicted from the context."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        _feed_forward(config, "hyper")
        self.context, self.object = ContextEncoder(config), ObjectEncoder(config)
        self.hyper = MLP((self.context.width, *config.modulation_hidden), activate_last=True)
        z, base_in, k = config.modulation_hidden[-1], self.object.width, config.hyper_rank
        self.actor = LowRankBase((base_in, *config.base_hidden, config.action_dim), k, z)
        self.critic = LowRankBase((base_in, *config.base_hidden, config.num_values), k, z)

    def forward(self, inputs: PolicyInputs) -> NetworkOutput:
        """Mean (B, A), values (B, R); no module weights (B, 0, 1)."""
        z = self.hyper(self.context(inputs))  # (B, Z)
        x = self.object(inputs)  # (B, E + S)
        return NetworkOutput(self.actor(x, z), self.critic(x, z), _no_modules(len(x), x), None)


class RoutedBase(nn.Module):
    """One soft-modularized base network: M modules per hidden layer, routed by a network
    that is conditioned on the context and on the previous layer's routing."""

    def __init__(self, dims: Sequence[int], modules: int, embedding: int, routing: int) -> None:
        super().__init__()
        hidden, m = list(dims[1:-1]), modules
        self.m = m
        self.first = nn.Linear(dims[0], m * hidden[0])  # every module sees the input
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for j, i in itertools.pairwise(hidden):
            bound = 1.0 / math.sqrt(j)
            self.weights.append(nn.Parameter(torch.empty(m, j, i).uniform_(-bound, bound)))
            self.biases.append(nn.Parameter(torch.empty(m, 1, i).uniform_(-bound, bound)))
        self.output = nn.Linear(hidden[-1], dims[-1])
        self.embed_context = nn.Linear(embedding, routing)
        self.embed_routes = nn.ModuleList(nn.Linear(m * m, routing) for _ in hidden[2:])
        self.route = nn.ModuleList(MLP((routing, routing, routing, m * m)) for _ in hidden[1:])

    def routes(self, z: Tensor) -> list[Tensor]:
        """(B, M, M) routing probabilities (destination, source) between hidden layers."""
        b, context = z.shape[0], self.embed_context(z)  # (B, R)
        routes: list[Tensor] = []
        for index, route in enumerate(self.route):
            features = context
            if index:  # conditioned on the previous layer's routing
                features = context * self.embed_routes[index - 1](routes[-1].reshape(b, -1))
            routes.append(torch.softmax(route(features).view(b, self.m, self.m), dim=-1))
        return routes

    def forward(self, x: Tensor, z: Tensor) -> tuple[Tensor, list[Tensor]]:
        """(B, J) -> (B, out), and the routings."""
        b, routes = x.shape[0], self.routes(z)
        y = hidden_activation(self.first(x).view(b, self.m, -1))  # (B, M, D_0)
        for route, weight, bias in zip(routes, self.weights, self.biases):
            mixed = (route @ y).transpose(0, 1)  # (M, B, D_l) module inputs
            y = hidden_activation(torch.baddbmm(bias, mixed, weight).transpose(0, 1))  # (B, M, D)
        return self.output(y.mean(dim=1)), routes


class SoftModularization(nn.Module):
    """UniCORN-SM: soft modularization with HAMnet's module count and base network size."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        _feed_forward(config, "sm")
        self.context, self.object = ContextEncoder(config), ObjectEncoder(config)
        self.trunk = MLP((self.context.width, *config.modulation_hidden), activate_last=True)
        z, base_in = config.modulation_hidden[-1], self.object.width
        args = (config.num_modules, z, config.routing_dim)
        self.actor = RoutedBase((base_in, *config.base_hidden, config.action_dim), *args)
        self.critic = RoutedBase((base_in, *config.base_hidden, config.num_values), *args)

    def forward(self, inputs: PolicyInputs) -> NetworkOutput:
        """Mean (B, A), values (B, R); module weights (B, L, M): for each routing, the mean
        weight each source module gets from the next layer's modules."""
        z = self.trunk(self.context(inputs))  # (B, Z)
        x = self.object(inputs)  # (B, E + S)
        mean, actor_routes = self.actor(x, z)
        values, critic_routes = self.critic(x, z)
        weights = torch.stack([r.mean(dim=1) for r in actor_routes + critic_routes], dim=1)
        return NetworkOutput(mean, values, weights, None)
