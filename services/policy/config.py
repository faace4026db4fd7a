"""Configuration of the policy networks: one frozen `ModelConfig` for every architecture.

Sizes are the paper's (Table tab:network, lines 909-946; baselines, lines 893-905; PPO's
log-std, Table tab:PPO). An architecture is a registered name plus a `ModelConfig`
(`hamnet.policy.registry`); the pair travels with the weights as JSON, so a receiver rebuilds
exactly the network the weights belong to.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from typing import Literal

from hamnet.sim.rewards import REWARD_NAMES

SceneInput = Literal["tokens", "env_code"]
"""What tells the modulation network about the scene: UniCORN scene tokens (local and global
clouds) or the oracle EnvCode (25 procedural-generation parameters, paper Table tab:env-code)."""


@dataclass(frozen=True)
class LogStdConfig:
    """The Gaussian actor's log standard deviation follows a schedule, not the gradient
    (Table tab:PPO: initial log std -0.4, decay factor -0.000367)."""

    initial: float = -0.4
    """log sigma at update 0 (same for every action component)."""
    decay: float = -0.000367
    """Added to log sigma after every PPO update (the paper's "log std. decay factor")."""
    minimum: float = -3.0
    """Floor of log sigma, so that a long run keeps some exploration."""

    def __post_init__(self) -> None:
        if self.decay > 0.0:
            raise ValueError(f"decay must be <= 0 (the std shrinks), got {self.decay}")
        if self.minimum > self.initial:
            raise ValueError(f"minimum {self.minimum} is above initial {self.initial}")


@dataclass(frozen=True)
class ModelConfig:
    """Every size of every architecture; each architecture reads the fields it needs."""

    num_tokens: int = 17
    """Tokens per cloud from the UniCORN encoder (16 patches + the [EMB] token at index 0)."""
    token_dim: int = 128
    """Width of a token (encoder embedding dim)."""
    attention_dim: int = 64
    """Cross-attention embedding dim (Table tab:network)."""
    object_heads: int = 8
    """Heads of the cross-attention over the object tokens."""
    scene_heads: int = 4
    """Heads of the cross-attentions over the local and global scene tokens."""
    scene_input: SceneInput = "tokens"
    """tokens (UniCORN-HAMnet) or env_code (the EnvCode-oracle ablation)."""
    env_code_dim: int = 25
    """Width of the EnvCode (paper Table tab:env-code)."""
    privileged: bool = True
    """Teacher inputs (object pose and velocity, physics parameters); False: the student's
    real-world-observable inputs only."""
    recurrent: bool = False
    """Student: a GRU in the modulation network and one in the base network."""
    base_memory: int = 128
    """Width of the base network's GRU (student only)."""
    modulation_hidden: tuple[int, ...] = (256, 256)
    """Modulation network MLP; its last width is the modulation embedding z_tau."""
    base_hidden: tuple[int, ...] = (256, 128, 128, 64)
    """Actor and critic base network hidden widths."""
    num_modules: int = 8
    """M, modules per base-network layer."""
    gates: bool = True
    """Per-unit gates 1 + linear(z_tau) on every base-network layer (off: the ablation)."""
    bias_weights: bool = False
    """Give biases their own softmax over modules, as the authors' code does (every
    parameter tensor gets one); False: one softmax per layer, as the paper writes."""
    mlp_hidden: tuple[int, ...] = (844, 422, 422, 211)
    """Monolithic baseline widths: the paper's (768, 384, 384, 192) scaled by 1.099 so that
    the MLP has as many parameters as our HAMnet (1.965 M), as the paper sized its MLP "to
    match the number of trainable parameters" (Appendix baseline-arch). Our inputs are
    narrower than the paper's, so its exact widths would give 1.69 M here."""
    hyper_rank: int = 16
    """Rank k of the hypernetwork baseline's generated weights W = W_l W_r."""
    routing_dim: int = 128
    """Soft modularization: width of the routing embedding and of its two-layer MLPs."""
    action_dim: int = 21
    """Raw action: joint residual (7), kp (7), damping ratio (7)."""
    num_values: int = len(REWARD_NAMES)
    """R, critic heads: one per reward term (REWARD_NAMES)."""
    log_std: LogStdConfig = field(default_factory=LogStdConfig)

    def __post_init__(self) -> None:
        for name in ("attention_dim", "num_modules", "hyper_rank", "routing_dim", "action_dim"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for heads in (self.object_heads, self.scene_heads):
            if heads < 1 or self.attention_dim % heads:
                raise ValueError(f"attention_dim {self.attention_dim} is not a multiple of {heads} heads")
        for name in ("modulation_hidden", "base_hidden", "mlp_hidden"):
            widths = getattr(self, name)
            if not widths or min(widths) < 1:
                raise ValueError(f"{name} needs at least one positive width, got {widths}")

    def to_json(self) -> str:
        """The config as JSON (what `WeightsAnnouncement.config_json` carries)."""
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> ModelConfig:
        """Inverse of `to_json`; an unknown or missing field is a ValueError naming it."""
        try:
            values = json.loads(text)
        except json.JSONDecodeError as error:
            raise ValueError(f"config is not JSON: {error}") from None
        if not isinstance(values, dict):
            raise ValueError("config JSON must be an object")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ValueError(f"unknown model config fields {unknown}")
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        if isinstance(values.get("log_std"), dict):
            values["log_std"] = LogStdConfig(**values["log_std"])
        return cls(**values)
