"""Configuration of the policy networks: one frozen `ModelConfig` for every architecture.

Sizes are the paper's (Table tab:network, lines 909-946; baselines, lines 893-905; PPO's
log-std, Table tab:PPO). An architecture is a registered name plus a `ModelConfig`
(`hamnet.policy.registry`); the pair travels with the weights as JSON, so a receiver rebuilds
exactly the network the weights belong to.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from typing import Any, Literal, TypeVar, get_args

from hamnet.fr3.limits import ACTION_DIM
from hamnet.policy.observation import ObservationSpec
from hamnet.runtime.counter import from_vectorized_steps
from hamnet.safety.config import ACTION_SPACES, ActionSpace
from hamnet.task.rewards import REWARD_NAMES

SceneInput = Literal["tokens", "env_code"]
"""What tells the modulation network about the scene: UniCORN scene tokens (local and global
clouds) or the oracle EnvCode (25 procedural-generation parameters, paper Table tab:env-code)."""

LOG_STD_RANGE = (-20.0, 2.0)
"""Bounds of the initial log sigma: below e^-20 the Gaussian's log-probabilities overflow
float32; above e^2 (sigma 7.4) the noise swamps every action component's range."""

T = TypeVar("T")


LogStdMode = Literal["learned", "schedule"]
"""How the Gaussian actor's log std moves (`LogStdConfig.mode`)."""

Initialization = Literal["orthogonal", "torch"]
"""How the actor and critic networks start (`ModelConfig.init`)."""


@dataclass(frozen=True)
class LogStdConfig:
    """The Gaussian actor's log standard deviation, one per action component, the same in
    every state. learned (default): a parameter the PPO loss trains from `initial`, as
    CleanRL and rsl_rl do: the policy cuts its own noise where that pays, instead of pushing
    its mean past the action bounds. schedule: a buffer following env_transitions
    (hamnet.runtime.counter): the authors' rule (ham/scripts/train.py:563-570, not trained:
    rss_train.yaml:544-546), log std -0.4 (rss_train.yaml:269) minus 0.000367 after every
    vectorized step k with k % 1024 == 0 of 1024 environments, no floor (paper Table
    tab:PPO: the same two numbers); with `horizon` > 0 the schedule runs linearly from
    `initial` to `final` over that many transitions instead, so a short run can shrink its
    noise within its own length (the authors' spans their 2e9)."""

    mode: LogStdMode = "learned"
    initial: float = -0.5
    """log sigma before any transition (same for every action component): -0.5 (std 0.61)
    learned, as CleanRL's anchor run on the easy stage (issue 27); the authors' schedule
    starts at -0.4 (preset `LOG_STD_AUTHORS`)."""
    decay: float = -0.000367
    """Added to log sigma once per `interval` (the paper's "log std. decay factor")."""
    interval: int = from_vectorized_steps(1024)
    """env_transitions per decay: 1024 vectorized steps of 1024 environments (train.py:564)."""
    horizon: int = 0
    """Schedule only: > 0, go linearly from `initial` to `final` over this many
    env_transitions, then stay (`decay` and `interval` unused); 0: the authors' decay."""
    final: float = -1.6
    """Schedule with a horizon: log sigma at its end (std 0.2; ours)."""

    def __post_init__(self) -> None:
        low, high = LOG_STD_RANGE
        for name in ("initial", "final"):
            if not low <= getattr(self, name) <= high:
                raise ValueError(
                    f"log_std.{name} must be in [{low:g}, {high:g}], got {getattr(self, name)}"
                )
        if self.mode not in get_args(LogStdMode):
            raise ValueError(
                f"log_std.mode must be one of {get_args(LogStdMode)}, got {self.mode!r}"
            )
        if self.horizon < 0:
            raise ValueError(f"log_std.horizon must be >= 0, got {self.horizon}")
        if not math.isfinite(self.decay) or self.decay > 0.0:
            raise ValueError(f"decay must be <= 0 (the std shrinks), got {self.decay}")
        if self.interval < 1:
            raise ValueError(f"interval must be >= 1, got {self.interval}")


LOG_STD_AUTHORS = LogStdConfig(mode="schedule", initial=-0.4)
"""The authors' log-std schedule (see `LogStdConfig`)."""


@dataclass(frozen=True)
class ModelConfig:
    """Every size of every architecture; each architecture reads the fields it needs."""

    num_tokens: int = 17
    """Tokens per cloud from the UniCORN encoder (16 patches, then the [EMB] token last)."""
    token_dim: int = 128
    """Width of a token (encoder embedding dim)."""
    object_attention_dim: int = 512
    """Embedding dim of the object cross-attention: the authors' obj_attn_emb_dim
    (hypernet_modular.py:518); the paper's Table tab:network says 64 (preset hamnet-paper)."""
    scene_attention_dim: int = 256
    """Embedding dim of the local and global scene cross-attentions: the authors'
    cross_big_emb_dim (hypernet_modular.py:513; cross_big, rss_train.yaml:338)."""
    attention_out: tuple[int, ...] = (256, 128)
    """Projection MLP after every cross-attention; its last width is the summary's (the
    authors' dim_local_proj, hypernet_modular.py:521, 650-656, 799-804)."""
    object_heads: int = 8
    """Heads of the cross-attention over the object tokens (hypernet_modular.py:517)."""
    scene_heads: int = 4
    """Heads of the scene cross-attentions (num_head, rss_train.yaml:321)."""
    clouds: bool = True
    """The network reads UniCORN tokens (object and scene); False for the state-only
    baseline, which a trainer runs without perception."""
    scene_input: SceneInput = "tokens"
    """tokens (UniCORN-HAMnet) or env_code (the EnvCode-oracle ablation)."""
    env_code_dim: int = 25
    """Width of the EnvCode (paper Table tab:env-code)."""
    privileged: bool = True
    """Teacher inputs (object pose and velocity, physics parameters); False: the student's
    real-world-observable inputs only."""
    recurrent: bool = False
    """Student: a GRU in the modulation network and one in the base network."""
    pose_readings: int = 1
    """Student: the object pose it reads is the mean of the pose estimator's last this many
    readings in the episode (`hamnet.policy.inputs.observed_state`); 1: the newest alone.
    The estimator's error is new every step (`PoseNoiseConfig`): the easy-push teacher fell
    from 0.496 to 0.410 held-out on one reading and rose to 0.523 on the mean of its last
    four (scripts/teacher_privileged.py, issue 28). The weights carry it, so every service
    that serves them averages alike."""
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
    bias_weights: bool = True
    """Give biases their own softmax over modules, as the authors' code does (every
    parameter tensor gets one: hypernet_modular.py:1029-1049); False: one softmax per
    layer, as the paper writes. The gates stay one per unit (docs/policy.md)."""
    mlp_hidden: tuple[int, ...] = (847, 424, 424, 212)
    """Monolithic baseline widths: the paper's (768, 384, 384, 192) scaled by 1.103 so that
    the MLP has as many parameters as our HAMnet (3.252 M), as the paper sized its MLP "to
    match the number of trainable parameters" (Appendix baseline-arch)."""
    state_hidden: tuple[int, ...] = (256, 256)
    """State-only baseline widths (MLP 2 x 256, the plain PPO a new user tries first)."""
    hyper_rank: int = 16
    """Rank k of the hypernetwork baseline's generated weights W = W_l W_r."""
    routing_dim: int = 128
    """Soft modularization: width of the routing embedding and of its two-layer MLPs."""
    shared_value_gradient: bool = False
    """True: the value loss trains what HAMnet's actor and critic share (context and object
    encoders, modulation network), one graph as the authors train it. False (ours): the
    critic reads those features with their gradient stopped (its own base network and
    modulation header still learn), so the shared layers learn from the policy loss alone. Measured on the easy stage (HAMnet, 2048 samples of the hour run): the value
    term's gradient on the 1.5 M shared parameters was 21x the policy term's (norms 1.93
    and 0.09; the total's cosine with the value term's 0.999), so the shared layers followed
    the critic, the global norm clip (1.0) cut every actor step to 40%, and the KL bound was
    spent on moves the policy loss did not ask for. The forward pass is the same either way."""
    action_dim: int = ACTION_DIM
    """Raw action: joint residual (J), kp (J), damping ratio (J)."""
    action_space: ActionSpace = "joint"
    """What the residual components ask for, and so how every safety filter serving these
    weights reads them (`ActionMagnitudeConfig.space`): "joint" (the paper's) or "paddle"
    (the paddle's twist). Weights written before the field read "joint"."""
    num_values: int = len(REWARD_NAMES)
    """R, critic heads: one per reward term (REWARD_NAMES)."""
    log_std: LogStdConfig = field(default_factory=LogStdConfig)
    init: Initialization = "orthogonal"
    """orthogonal: the actor's and critic's layers orthogonal (gain sqrt 2), biases 0, the
    actor's output layer scaled to 0.01 and the critic's to 1 (CleanRL, rsl_rl): the mean
    starts near 0 and one Adam step at 3e-4 moves the policy by KL 0.003 (0.09 at torch's
    default, measured on the easy stage: issue 27). torch: PyTorch's defaults (the authors')."""

    def __post_init__(self) -> None:
        if self.init not in get_args(Initialization):
            raise ValueError(f"init must be one of {get_args(Initialization)}, got {self.init!r}")
        if self.action_space not in ACTION_SPACES:
            raise ValueError(
                f"action_space must be one of {ACTION_SPACES}, got {self.action_space!r}"
            )
        if self.scene_input not in get_args(SceneInput):
            raise ValueError(
                f"scene_input must be one of {get_args(SceneInput)}, got {self.scene_input!r}"
            )
        for name in (
            "num_tokens",
            "token_dim",
            "env_code_dim",
            "base_memory",
            "num_modules",
            "hyper_rank",
            "routing_dim",
            "action_dim",
            "num_values",
            "pose_readings",
        ):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.privileged and self.pose_readings != 1:
            raise ValueError(
                "pose_readings averages a student's pose estimate; a privileged policy reads "
                f"the true pose (pose_readings 1), got {self.pose_readings}"
            )
        for dim, heads in (
            (self.object_attention_dim, self.object_heads),
            (self.scene_attention_dim, self.scene_heads),
        ):
            if heads < 1 or dim < 1 or dim % heads:
                raise ValueError(f"attention dim {dim} is not a positive multiple of {heads} heads")
        for name in (
            "modulation_hidden",
            "base_hidden",
            "mlp_hidden",
            "attention_out",
            "state_hidden",
        ):
            widths = getattr(self, name)
            if not widths or min(widths) < 1:
                raise ValueError(f"{name} needs at least one positive width, got {widths}")

    @property
    def observation(self) -> ObservationSpec:
        """Names and widths of the non-geometric inputs."""
        return ObservationSpec(privileged=self.privileged, action_dim=self.action_dim)

    def to_json(self) -> str:
        """The config as JSON (what `WeightsAnnouncement.config_json` carries)."""
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> ModelConfig:
        """Inverse of `to_json`; an unknown field, or a value of the wrong type or out of
        range, is a ValueError or TypeError naming it (missing fields take their defaults)."""
        try:
            values = json.loads(text)
        except json.JSONDecodeError as error:
            raise ValueError(f"config is not JSON: {error}") from None
        return _from_dict(cls, values, "config")


def _from_dict(cls: type[T], values: Any, name: str) -> T:
    """Config `cls` from JSON `values`, each checked against the type of its default."""
    if not isinstance(values, dict):
        raise TypeError(f"{name} must be a JSON object, got {values!r}")
    unknown = sorted(set(values) - {f.name for f in dataclasses.fields(cls)})  # type: ignore[arg-type]
    if unknown:
        raise ValueError(f"unknown model config fields {unknown}")
    defaults = cls()
    return cls(**{k: _typed(v, getattr(defaults, k), k) for k, v in values.items()})


def _typed(value: Any, default: Any, name: str) -> Any:
    """JSON `value` as the type of `default` (a nested config, bool, int, finite float, str or
    tuple of those); a TypeError naming the field otherwise."""
    if dataclasses.is_dataclass(default):
        return _from_dict(type(default), value, name)
    if isinstance(default, tuple):
        if not isinstance(value, list):
            raise TypeError(f"{name} must be a JSON list, got {value!r}")
        return tuple(_typed(v, default[0], name) for v in value) if default else tuple(value)
    if isinstance(default, bool) or isinstance(value, bool):
        fits = isinstance(value, bool) and isinstance(default, bool)
    elif isinstance(default, float):
        fits = isinstance(value, (int, float)) and math.isfinite(value)
    else:
        fits = isinstance(value, type(default))
    if not fits:
        raise TypeError(f"{name} must be of type {type(default).__name__}, got {value!r}")
    return value
