"""Every policy architecture by name: the network class and its preset `ModelConfig`.

`build(name)` makes a `Policy` with the preset; `build(name, config)` with a config read
from weights metadata. The names are the ones on the wire (`WeightsAnnouncement.architecture`)
and on the command line (`hamnet policy --random-init NAME`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import torch
from torch import nn

from hamnet.policy.baselines import HyperNetwork, MonolithicMLP, SoftModularization, StateMLP
from hamnet.policy.config import ModelConfig
from hamnet.policy.init import initialize
from hamnet.policy.networks import HAMNet
from hamnet.policy.policy import Policy


@dataclass(frozen=True)
class Architecture:
    """One registered architecture."""

    network: type[nn.Module]
    config: ModelConfig
    """Preset configuration."""
    summary: str
    """What it is, in the paper's words."""
    paper_params: str
    """Parameter count the paper reports for it, or why it reports none."""


ARCHITECTURES: dict[str, Architecture] = {}
"""Name -> architecture, in the order `--print-params` lists them."""


def register(name: str, network: type[nn.Module], summary: str, paper: str, **preset) -> None:
    """Add an architecture under `name`; `preset` overrides ModelConfig's defaults."""
    if name in ARCHITECTURES:
        raise ValueError(f"architecture {name!r} is registered twice")
    ARCHITECTURES[name] = Architecture(network, ModelConfig(**preset), summary, paper)


register(
    "hamnet",
    HAMNet,
    "UniCORN-HAMnet teacher (modules + gates)",
    "about 1.76 M: Table tab:mlp-scale sizes the MLP to match it",
)
register(
    "hamnet-paper",
    HAMNet,
    "HAMnet as the paper's text sizes it: cross-attention "
    "width 64 (Table tab:network), one softmax and gate per layer",
    "not reported",
    object_attention_dim=64,
    scene_attention_dim=64,
    attention_out=(64,),
    bias_weights=False,
)
register("hamnet-nogate", HAMNet, "HAMnet without gates (ablation)", "not reported", gates=False)
register(
    "hamnet-envcode",
    HAMNet,
    "EnvCode-HAMnet: oracle scene code instead of scene tokens",
    "not reported",
    scene_input="env_code",
)
register(
    "mlp",
    MonolithicMLP,
    "UniCORN-MONO: MLP (847, 424, 424, 212), the paper's "
    "(768, 384, 384, 192) scaled to HAMnet's parameter count",
    "1.76 M (Table tab:mlp-scale), matched to HAMnet",
)
register("hyper", HyperNetwork, "UniCORN-HYPER: low-rank hypernetwork (rank 16)", "not reported")
register("sm", SoftModularization, "UniCORN-SM: soft modularization", "not reported")
register(
    "state-mlp",
    StateMLP,
    "plain PPO baseline: MLP (256, 256) on the privileged state, no clouds",
    "not in the paper",
    clouds=False,
)
register(
    "student",
    HAMNet,
    "student: HAMnet with GRUs, real-robot inputs only",
    "not reported",
    privileged=False,
    recurrent=True,
)


def architecture(name: str) -> Architecture:
    """The registered architecture `name`; a ValueError lists the known names."""
    if name not in ARCHITECTURES:
        raise ValueError(f"unknown architecture {name!r}; known: {', '.join(ARCHITECTURES)}")
    return ARCHITECTURES[name]


def build(name: str, config: ModelConfig | None = None, seed: int | None = None) -> Policy:
    """A freshly initialised policy of architecture `name` (preset config unless given)."""
    entry = architecture(name)
    config = entry.config if config is None else config
    if seed is not None:
        torch.manual_seed(seed)
    network = entry.network(config)
    if config.init == "orthogonal":
        initialize(network)
    return Policy(name, config, network)


def with_changes(name: str, **changes) -> ModelConfig:
    """The preset config of `name` with some fields changed (tests, benchmarks, scaling)."""
    return dataclasses.replace(architecture(name).config, **changes)
