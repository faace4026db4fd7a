"""Stage 6's configuration and outputs, and its simplest generator.

`TrajectoryConfig` holds the limits, clocks and margins of the references; `References`
is what a generator produces for one policy period (q_ref, dq_ref, ddq_ref at the control
rate, (B, S, J), with a `Plan` code per environment) and `ReferenceState` where the next
period starts. `TargetReferences` puts the joint target itself on every sample (training
and fine-tuning profiles); the jerk-limited Ruckig generator of the deploy profile, with the
same interface, is `ruckig_references.TrajectoryGenerator`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.fr3.limits import FR3Limits


@dataclass(frozen=True)
class TrajectoryConfig:
    """Limits, clocks and margins of the jerk-limited reference."""

    dynamics_factor: float = 0.5
    """Fraction of the FR3's dq_max, ddq_max and jerk_max the reference may use, in (0, 1]."""
    control_rate_hz: float = 80.0
    """Samples per second of the reference (80 Hz: the sim's torque ticks; 1000: libfranka)."""
    policy_period_s: float = 0.1
    """Time covered by one call of `step`, s (10 Hz policy)."""
    target_margin: float = 1e-6
    """Targets are kept this far inside the joint range, rad, so Ruckig's end-point precision
    (1e-8 rad) cannot put the reference outside it."""
    limits: FR3Limits = field(default_factory=FR3Limits)
    """The robot's limits (Franka's FR3 control-parameter table)."""

    def __post_init__(self) -> None:
        if not 0.0 < self.dynamics_factor <= 1.0:
            raise ValueError(f"dynamics_factor must be in (0, 1], got {self.dynamics_factor}")
        if self.control_rate_hz <= 0.0 or self.policy_period_s <= 0.0:
            raise ValueError("control_rate_hz and policy_period_s must be positive")
        samples = self.policy_period_s * self.control_rate_hz
        if samples < 1.0 or abs(samples - round(samples)) > 1e-6:
            raise ValueError(
                f"policy_period_s * control_rate_hz must be a whole number, got {samples}"
            )
        if not 0.0 <= self.target_margin < 0.01:
            raise ValueError("target_margin must be in [0, 0.01) rad")

    @property
    def samples_per_period(self) -> int:
        """S: reference samples per policy period."""
        return round(self.policy_period_s * self.control_rate_hz)

    @property
    def control_period_s(self) -> float:
        """dt: time between two reference samples, s."""
        return self.policy_period_s / self.samples_per_period

    @property
    def dq_max(self) -> np.ndarray:
        """Velocity limit of the reference, (J,), rad/s."""
        return self.dynamics_factor * self.limits.dq_max

    @property
    def ddq_max(self) -> np.ndarray:
        """Acceleration limit of the reference, (J,), rad/s^2."""
        return self.dynamics_factor * self.limits.ddq_max

    @property
    def jerk_max(self) -> np.ndarray:
        """Jerk limit of the reference, (J,), rad/s^3."""
        return self.dynamics_factor * self.limits.jerk_max


class Plan(IntEnum):
    """What an environment's reference did during a period (the stage's reason code)."""

    TARGET = 0
    """Moved towards the target, joints synchronised (phase when possible, else time)."""
    STOP = 1
    """Braked to rest and held: `stop` was requested."""
    STOP_INVALID_TARGET = 2
    """Braked to rest and held: Ruckig refused the target (non-finite, or no plan found)."""
    STOP_RANGE = 3
    """Braked towards rest: the plan to the target left the joint range."""
    HOLD = 4
    """Held position with zero velocity: even the stop could not be planned (never seen)."""


@dataclass(frozen=True)
class ReferenceState:
    """Reference state of every environment at one instant."""

    q: np.ndarray
    """Positions, (B, J), rad."""
    dq: np.ndarray
    """Velocities, (B, J), rad/s."""
    ddq: np.ndarray
    """Accelerations, (B, J), rad/s^2."""


@dataclass(frozen=True)
class References:
    """One policy period of references for every environment, and what was done."""

    q_ref: np.ndarray
    """Positions at t = dt, 2 dt, ..., S dt after the period start, (B, S, J), rad."""
    dq_ref: np.ndarray
    """Velocities at the same times, (B, S, J), rad/s."""
    ddq_ref: np.ndarray
    """Accelerations at the same times, (B, S, J), rad/s^2."""
    plan: np.ndarray
    """`Plan` code per environment, (B,), int8."""
    result: np.ndarray
    """Ruckig's `Result` for the target plan, (B,), int: 0 (Working) when a plan was found,
    < 0 for Ruckig's errors (-100 also for a non-finite target); 0 for stopping environments."""
    reached: np.ndarray
    """The reference is at its target (or at rest after a stop) by the period's end, (B,)."""

    @property
    def end_state(self) -> ReferenceState:
        """State at the end of the period, where the next period starts, (B, J) each."""
        return ReferenceState(self.q_ref[:, -1], self.dq_ref[:, -1], self.ddq_ref[:, -1])


class Stoppable:
    """Per-environment stop flags of a reference generator (watchdog, e-stop): a stopped
    environment ignores its targets from the next `step` on, until `resume` or `reset`.
    How it stops is the generator's: Ruckig brakes to rest, `TargetReferences` holds."""

    _stopping: np.ndarray
    """(B,) bool."""

    @property
    def stopping(self) -> np.ndarray:
        """Environments stopping or stopped, (B,) bool (a copy)."""
        return self._stopping.copy()

    def stop(self, env_ids: np.ndarray) -> None:
        """Stop these environments, (N,) int indices or a (B,) bool mask."""
        self._stopping[env_ids] = True

    def resume(self, env_ids: np.ndarray) -> None:
        """Follow targets again from wherever the stop has brought these environments."""
        self._stopping[env_ids] = False


class TargetReferences(Stoppable):
    """Stage 6 of the training and fine-tuning profiles: the joint target itself on every
    control sample, so the impedance controller receives it directly (the paper's MDP; the
    authors hold their jpos target over the 8 control steps of a policy step, franka.py:
    1405-1415). The same interface as `TrajectoryGenerator`, batched (no per-environment
    loop). A stopped environment, or a non-finite target, holds its last reference at once:
    there is no braking profile, since this runs on simulated robots only."""

    def __init__(self, q: np.ndarray, config: TrajectoryConfig | None = None) -> None:
        """Start every environment at rest at q (B, J), rad; `config` gives S (its clocks)."""
        self.config = config if config is not None else TrajectoryConfig()
        self._q = joint_rows(q)  # (B, J), rad
        self.num_envs = self._q.shape[0]
        self._stopping = np.zeros(self.num_envs, dtype=bool)  # (B,)

    @property
    def state(self) -> ReferenceState:
        """Where the next period starts, (B, J) each (copies): at rest on the last reference."""
        return ReferenceState(self._q.copy(), np.zeros_like(self._q), np.zeros_like(self._q))

    def reset(
        self,
        env_ids: np.ndarray,
        q: np.ndarray,
        dq: np.ndarray | None = None,
        ddq: np.ndarray | None = None,
    ) -> None:
        """Re-anchor environments at measured positions q (N, J) (dq, ddq are not used)."""
        self._q[env_ids] = joint_rows(q)
        self._stopping[env_ids] = False

    def step(self, q_target: np.ndarray) -> References:
        """q_ref (B, S, J) = the target (B, J) on every sample; velocities zero."""
        q_target = np.asarray(q_target, dtype=np.float64)  # (B, J)
        invalid = ~np.isfinite(q_target).all(axis=1)  # (B,)
        hold = self._stopping | invalid
        self._q = np.where(hold[:, None], self._q, q_target)  # (B, J)
        q_ref = np.repeat(self._q[:, None], self.config.samples_per_period, axis=1)  # (B, S, J)
        plan = np.full(self.num_envs, Plan.TARGET, dtype=np.int8)
        plan[self._stopping] = Plan.STOP
        plan[invalid & ~self._stopping] = Plan.STOP_INVALID_TARGET
        return References(
            q_ref,
            np.zeros_like(q_ref),
            np.zeros_like(q_ref),
            plan,
            result=np.where(invalid & ~self._stopping, -100, 0),
            reached=np.ones(self.num_envs, dtype=bool),
        )


def joint_rows(q: np.ndarray) -> np.ndarray:
    """Joint values as float64 (N, J), or ValueError when not finite or not (N, J)."""
    q = np.array(q, dtype=np.float64)  # (N, J)
    if q.ndim != 2 or q.shape[1] != J or not np.all(np.isfinite(q)):
        raise ValueError(f"joint values must be finite and (N, {J}), got shape {q.shape}")
    return q
