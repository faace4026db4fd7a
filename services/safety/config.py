"""Configuration of the safety core: one frozen `SafetyConfig` with one nested config per stage.

Values are the paper's where it gives them (Table tab:sim2real-params, paper lines 761-777;
Algorithm eq:cclip, lines 788-801) and the project's facts otherwise (ARCHITECTURE.md:
kp in [10, 200], rho in [0.3, 2.0], targets inside the central 90% of each joint range).
Every stage has an `enabled` switch; the nested config's field name is the stage's name
everywhere (stage function, statistics, safety events).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

from hamnet.runtime.counter import from_vectorized_steps

Squash = Literal["clip", "tanh"]
"""How a raw action component becomes u in [-1, 1] (see `ActionMagnitudeConfig.squash`)."""

MagnitudeMode = Literal["scale", "clip"]
"""How the bound xi acts on the residual (see `ActionMagnitudeConfig.mode`)."""

ActionSpace = Literal["joint", "paddle"]
"""What the residual's components ask for (see `ActionMagnitudeConfig.space`)."""

ACTION_SPACES: tuple[ActionSpace, ...] = ("joint", "paddle")
"""Every action space, the paper's first."""

CartesianRows = Literal["linear", "full"]
"""Which rows of the end-effector Jacobian define Delta x (see `CartesianClipConfig.rows`)."""

ReferenceMode = Literal["ruckig", "target"]
"""What stage 6 sends the executor (see `SafetyConfig.references`)."""

Profile = Literal["training", "finetune", "deploy"]
"""Named settings of the filter for one use (see `with_profile`)."""

PROFILES: tuple[Profile, ...] = ("training", "finetune", "deploy")
"""Every profile, in the order of the project's stages: train, fine-tune for the real robot,
deploy on it."""


def _positive(owner: object, *names: str) -> None:
    for name in names:
        value = getattr(owner, name)
        if not value > 0.0:
            raise ValueError(f"{type(owner).__name__}.{name} must be > 0, got {value}")


@dataclass(frozen=True)
class AnnealingConfig:
    """Geometric annealing over env_transitions (hamnet.runtime.counter; paper line 756):
    every N_s transitions the value is multiplied by (end/start)^(N_s/N_t), so it reaches its
    end value after N_t. The paper's N_s = 1024 and N_t = 2e6 (Table tab:sim2real-params) count
    vectorized steps of 1024 environments, as the authors' other schedules do
    (ham/scripts/env_wrappers.py:1128-1129); the defaults are those numbers in transitions."""

    start_step: int = 0
    """env_transitions at which annealing begins; before it the start value holds."""
    interval: int = from_vectorized_steps(1024)
    """N_s in env_transitions: 1024 vectorized steps of 1024 environments."""
    num_steps: int = from_vectorized_steps(2e6)
    """N_t in env_transitions: 2e6 vectorized steps of 1024 environments (2.048e9)."""

    def __post_init__(self) -> None:
        if self.start_step < 0:
            raise ValueError(f"start_step must be >= 0, got {self.start_step}")
        if self.interval < 1:
            raise ValueError(f"interval (N_s) must be >= 1, got {self.interval}")
        if self.num_steps < 1:
            raise ValueError(f"num_steps (N_t) must be >= 1, got {self.num_steps}")


@dataclass(frozen=True)
class NonfiniteGuardConfig:
    """Stage 1: reject actions with NaN/Inf or the wrong shape, and non-finite robot states."""

    enabled: bool = True
    """Off only to time the other stages: non-finite actions then flow through unchecked and a
    wrongly shaped action raises ValueError."""
    hold_kp: float = 100.0
    """Stiffness of a hold before the environment's first accepted action, N m/rad."""
    hold_rho: float = 1.0
    """Damping ratio of that hold (kd = rho*sqrt(kp))."""

    def __post_init__(self) -> None:
        _positive(self, "hold_kp", "hold_rho")


@dataclass(frozen=True)
class ActionMagnitudeConfig:
    """Stage 2: raw action (B, 21) = [dq | kp | rho] (7 each) to physical values, with the
    action-magnitude bound xi per joint group annealed from xi_max to xi* (paper lines
    753-757, Table tab:sim2real-params)."""

    enabled: bool = True
    """Off: xi stays at xi_max (no curriculum); the mapping to physical ranges still runs."""
    squash: Squash = "clip"
    """Raw component a to u in [-1, 1]: "clip" (np.clip) or "tanh". The paper is silent; clip
    keeps a Gaussian policy's mean linear inside [-1, 1]."""
    mode: MagnitudeMode = "scale"
    """"scale": dq = xi*u, the policy's whole output range shrinks with xi (the bound on what
    the policy can output, line 755); "clip": dq = clip(xi_max*u, -xi, xi). Joint space only."""
    space: ActionSpace = "joint"
    """"joint" (the paper's): the first 7 components are joint residuals. "paddle": the first
    6 are the paddle's twist per policy step, [linear | angular] in the world frame scaled by
    `twist_linear` and `twist_angular`, turned into the joint residual by damped least
    squares on the paddle's Jacobian at the measured posture, then clipped to +-xi; the 7th
    is unused (the minimum-norm solution leaves the null space alone). A push is nearly a
    constant twist but a precise function of the posture in joints (docs/trainer-history.md,
    "A scripted reference"). A policy's weights say which space it was trained in
    (`ModelConfig.action_space`)."""
    twist_linear: float = 0.03
    """Paddle translation per policy step at u = 1, m ("paddle" space): 1.5x the scripted
    pusher's 2 cm push step (`hamnet.evaluation.scripted_pusher`), so a policy can push at
    the script's speed inside its range (the measured A/B, docs/trainer-history.md)."""
    twist_angular: float = 0.1
    """Paddle rotation per policy step at u = 1, rad ("paddle" space; the same A/B)."""
    twist_damping: float = 1e-3
    """lambda of the damped least squares from twist to joints ("paddle" space): the scripted
    pusher's (`PusherConfig.damping`)."""
    xi_max_large: float = 0.26
    """xi_max for the large joints 1-4, rad per policy step."""
    xi_star_large: float = 0.16
    """xi* (target) for the large joints 1-4, rad per policy step."""
    xi_max_small: float = 0.21
    """xi_max for the small joints 5-7, rad per policy step."""
    xi_star_small: float = 0.08
    """xi* (target) for the small joints 5-7, rad per policy step."""
    num_large_joints: int = 4
    """The first this-many joints are "large" (FR3: joints 1-4, 87 N m motors)."""
    kp_min: float = 10.0
    """Stiffness at u = -1, N m/rad (linear in u up to kp_max)."""
    kp_max: float = 200.0
    """Stiffness at u = +1, N m/rad."""
    rho_min: float = 0.3
    """Damping ratio at u = -1 (linear in u up to rho_max); kd = rho*sqrt(kp)."""
    rho_max: float = 2.0
    """Damping ratio at u = +1."""
    annealing: AnnealingConfig = field(default_factory=AnnealingConfig)
    """Schedule of xi from xi_max to xi*."""

    def __post_init__(self) -> None:
        if self.squash not in ("clip", "tanh"):
            raise ValueError(f"squash must be 'clip' or 'tanh', got {self.squash!r}")
        if self.mode not in ("scale", "clip"):
            raise ValueError(f"mode must be 'scale' or 'clip', got {self.mode!r}")
        if self.space not in ACTION_SPACES:
            raise ValueError(f"space must be one of {ACTION_SPACES}, got {self.space!r}")
        _positive(self, "twist_linear", "twist_angular", "twist_damping")
        _positive(self, "xi_max_large", "xi_star_large", "xi_max_small", "xi_star_small")
        _positive(self, "kp_min", "rho_min")
        if not 0 <= self.num_large_joints <= 7:
            raise ValueError(f"num_large_joints must be in [0, 7], got {self.num_large_joints}")
        if self.kp_max < self.kp_min or self.rho_max < self.rho_min:
            raise ValueError("kp and rho ranges need min <= max")


@dataclass(frozen=True)
class CartesianClipConfig:
    """Stage 3: Algorithm eq:cclip (paper lines 788-804) with eps_x annealed from eps_x_max
    to eps_x."""

    enabled: bool = True
    """Off: the residual passes unchanged."""
    eps_x: float = 0.12
    """epsilon_x, target bound on the predicted end-effector motion ||J dq|| per policy step
    (m for "linear" rows)."""
    eps_x_max: float = 0.24
    """epsilon_x^max, the bound at the start of its annealing."""
    damping: float = 0.01
    """lambda of the damped least squares (line 798); the paper gives no value. Small against
    the FR3's translational singular values in its workspace (about 0.1-0.7 m/rad), so one
    pass leaves at most (lambda/2)*||dq|| of excess."""
    rows: CartesianRows = "linear"
    """"linear": Delta x is the paddle's translation (J rows 0-2, metres), which makes eps_x a
    distance; "full": the 6-d twist (rad counted as m). The paper does not say."""
    iterations: int = 1
    """Passes of the algorithm; 1 is the paper, each further pass removes what the damping
    left of the previous pass's excess."""
    annealing: AnnealingConfig = field(default_factory=AnnealingConfig)
    """Schedule of eps_x from eps_x_max down to eps_x (the paper anneals it while fine-tuning:
    set start_step to where fine-tuning begins)."""

    def __post_init__(self) -> None:
        _positive(self, "eps_x", "eps_x_max")
        if self.damping < 0.0:
            raise ValueError(f"damping must be >= 0, got {self.damping}")
        if self.rows not in ("linear", "full"):
            raise ValueError(f"rows must be 'linear' or 'full', got {self.rows!r}")
        if self.iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {self.iterations}")


@dataclass(frozen=True)
class ResidualSmoothingConfig:
    """Stage 4: EMA of the joint residual, dq_bar_t = alpha*dq_t + (1-alpha)*dq_bar_{t-1}
    (paper line 808; its "alpha q_t" is the residual Delta q_t)."""

    enabled: bool = True
    """Off: alpha = 1, the residual passes unchanged."""
    alpha: float = 0.8
    """alpha, weight of the newest residual (Table tab:sim2real-params)."""

    def __post_init__(self) -> None:
        if not 0.0 < self.alpha <= 1.0:
            raise ValueError(f"alpha must be in (0, 1], got {self.alpha}")


@dataclass(frozen=True)
class JointLimitsConfig:
    """Stage 5: the joint target q + dq_bar stays inside the central part of each range."""

    enabled: bool = True
    """Off: targets are not clipped (the executor's own limits then apply)."""
    central_fraction: float = 0.9
    """Share of each FR3 joint range the target may use, centred (0.9: 5% margin each side)."""

    def __post_init__(self) -> None:
        if not 0.0 < self.central_fraction <= 1.0:
            raise ValueError(f"central_fraction must be in (0, 1], got {self.central_fraction}")


@dataclass(frozen=True)
class TorquePreclipConfig:
    """Stage 7: reduce kp (and kd with rho kept) where kp*|q_ref - q| + kd*|qdot| would exceed
    (1 - margin)*tau_max; that limit is also the executor's hard clip, tau_limit. Reduced
    gains may fall below kp_min: the torque bound wins over the action range."""

    enabled: bool = True
    """Off: gains pass unchanged; tau_limit is still output for the executor's hard clip."""
    margin: float = 0.1
    """Share of the FR3 torque limit kept in reserve (gravity-model error, impacts)."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.margin < 1.0:
            raise ValueError(f"margin must be in [0, 1), got {self.margin}")


@dataclass(frozen=True)
class SafetyConfig:
    """The safety core: stages 1-5 and 7 (stage 6, trajectory generation, comes after
    `filter` has produced the joint target)."""

    nonfinite_guard: NonfiniteGuardConfig = field(default_factory=NonfiniteGuardConfig)
    """Stage 1."""
    action_magnitude: ActionMagnitudeConfig = field(default_factory=ActionMagnitudeConfig)
    """Stage 2."""
    cartesian_clip: CartesianClipConfig = field(default_factory=CartesianClipConfig)
    """Stage 3."""
    residual_smoothing: ResidualSmoothingConfig = field(default_factory=ResidualSmoothingConfig)
    """Stage 4."""
    joint_limits: JointLimitsConfig = field(default_factory=JointLimitsConfig)
    """Stage 5."""
    torque_preclip: TorquePreclipConfig = field(default_factory=TorquePreclipConfig)
    """Stage 7."""
    references: ReferenceMode = "ruckig"
    """Stage 6: "ruckig", jerk-limited references towards the target (the real robot);
    "target", the target itself on every control sample, so the impedance controller receives
    it directly (the paper's MDP; the authors' jpos control, franka.py:1405-1415)."""

    def __post_init__(self) -> None:
        if self.references not in ("ruckig", "target"):
            raise ValueError(f"references must be 'ruckig' or 'target', got {self.references!r}")


def with_profile(profile: Profile, config: SafetyConfig | None = None) -> SafetyConfig:
    """`config` (the defaults when None) with the stage switches of a named profile.

    - "training": the paper's MDP, as the authors train it. The action goes through the
      residual bound xi (annealed), the EMA, the joint band and the executor's torque clip at
      the FR3's full torque limit (Isaac Gym clips efforts at the URDF's limit), and reaches the
      impedance controller otherwise unchanged: no Cartesian clip, no torque pre-clip, the
      target on every control sample (no Ruckig). Batched, with no per-environment loop.
    - "finetune": training plus the Cartesian clip with eps_x annealed (paper lines 803-804,
      the sim-to-real fine-tuning stage); set `cartesian_clip.annealing.start_step` to the
      env_transitions where fine-tuning starts. Its Jacobians come from Pinocchio, one
      environment at a time (about 1 us each).
    - "deploy": `config` as given, by default every stage with Ruckig references and the torque
      pre-clip (the real robot, and evaluation runs that ask for them).
    Other fields (xi, eps_x, alpha, the band, the annealing) come from `config`.
    """
    config = config if config is not None else SafetyConfig()
    if profile == "deploy":
        return config
    if profile not in PROFILES:
        raise ValueError(f"profile must be one of {PROFILES}, got {profile!r}")
    return replace(
        config,
        cartesian_clip=replace(config.cartesian_clip, enabled=profile == "finetune"),
        torque_preclip=replace(config.torque_preclip, enabled=False, margin=0.0),
        references="target",
    )


def in_action_space(config: SafetyConfig, space: ActionSpace) -> SafetyConfig:
    """`config` reading actions in `space`: the filter of a policy trained in that space
    (`ModelConfig.action_space`)."""
    return replace(config, action_magnitude=replace(config.action_magnitude, space=space))
