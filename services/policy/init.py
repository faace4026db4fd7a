"""Orthogonal initialization of the actor and critic (`ModelConfig.init` "orthogonal").

Layers orthogonal with gain sqrt(2) and zero biases, the actor's output layer scaled to
0.01 and the critic's to 1, as CleanRL and rsl_rl start PPO's networks: the action mean
starts near 0 whatever the inputs, and one Adam step at 3e-4 moves the policy by KL 0.003
instead of 0.09 at PyTorch's default initialization behind LayerNorm + tanh (measured on the
easy stage, issue 27). Only the actor and critic are touched: the encoders and HAMnet's
modulation heads keep their own initialization (the gates' U(-0.008, 0.008)).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from hamnet.policy.layers import ModularLinear

HIDDEN_GAIN = math.sqrt(2.0)
"""Gain of hidden layers (CleanRL's `layer_init` default)."""
ACTOR_OUTPUT_GAIN = 0.01
"""Gain of the actor's output layer: a mean near 0 (CleanRL's `std=0.01`)."""
CRITIC_OUTPUT_GAIN = 1.0
"""Gain of the critic's output layer (CleanRL's `std=1.0`)."""


def initialize(network: nn.Module) -> None:
    """Re-initialize `network.actor` and `network.critic` in place (see the module)."""
    heads = ((network.actor, ACTOR_OUTPUT_GAIN), (network.critic, CRITIC_OUTPUT_GAIN))
    for head, output_gain in heads:
        layers = [m for m in head.modules() if isinstance(m, (nn.Linear, ModularLinear))]
        output = getattr(head, "output", layers[-1])  # a routed base names its output layer
        for layer in layers:
            _orthogonal(layer, output_gain if layer is output else HIDDEN_GAIN)


@torch.no_grad()
def _orthogonal(layer: nn.Module, gain: float) -> None:
    """Orthogonal weights (each module's (J, I) matrix in a bank) and zero biases."""
    if isinstance(layer, ModularLinear):
        for weight in layer.weight:  # (J, I) per module
            nn.init.orthogonal_(weight, gain)
    else:
        nn.init.orthogonal_(layer.weight, gain)
    if layer.bias is not None:
        layer.bias.zero_()
