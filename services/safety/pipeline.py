"""The safety core: raw policy action (B, 21) and robot state to a safe joint command.

`filter_action` is a pure function of (config, state, action, q, dq, step) returning a
`FilterResult` and the next `SafetyState`; `SafetyCore` holds that state, the Pinocchio model
and running statistics for the shell and the trainer. Stages, in order:

    1 nonfinite_guard -> 2 action_magnitude -> 3 cartesian_clip -> 4 residual_smoothing
    -> 5 joint_limits -> [6 trajectory, outside this core] -> 7 torque_preclip

Seam for stage 6: `filter` returns the joint target q_target (B, J) and gains already
pre-clipped against that target. Trajectory generation (Ruckig) then turns q_target into
reference samples q_ref (B, S, J); `recheck_torque` re-applies stage 7 to those samples, since
a reference may overshoot the target. A rejected environment (reason != 0) holds its last
safe target with its last safe gains, still pre-clipped against the current state.
Legend: B environments, J = 7 joints, S control samples.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hamnet.fr3.limits import FR3, NUM_JOINTS, Q_HOME
from hamnet.fr3.model import load_pinocchio
from hamnet.safety import stages
from hamnet.safety.cartesian import JACOBIAN_ROWS, cartesian_clip, ee_jacobians
from hamnet.safety.config import SafetyConfig
from hamnet.safety.schedule import ScheduleValues, per_joint, schedule_values
from hamnet.safety.stats import StageReport, StageStats, StatsAccumulator, stage_report, summarize

Jacobians = Callable[[np.ndarray], np.ndarray]
"""q (N, J) -> the paddle's world-aligned Jacobians (N, 6, J) [linear; angular] at those
configurations (`cartesian.ee_jacobians(..., "full")`)."""


@dataclass(frozen=True)
class SafetyState:
    """What the core remembers per environment between calls."""

    q_target: np.ndarray
    """(B, J) last safe joint target, rad: what a rejected action holds."""
    kp: np.ndarray
    """(B, J) stiffness that came with it (before torque pre-clipping), N m/rad."""
    rho: np.ndarray
    """(B, J) damping ratio that came with it."""
    dq_smoothed: np.ndarray
    """(B, J) dq_bar_{t-1}, the EMA memory, rad; zero at an episode's start."""
    has_target: np.ndarray
    """(B,) bool, q_target is set (from a reset or an accepted action)."""

    @property
    def num_envs(self) -> int:
        """B."""
        return self.has_target.shape[0]


@dataclass(frozen=True)
class FilterResult:
    """What the core did with one batch of actions: the safe command and why it differs."""

    q_target: np.ndarray
    """(B, J) safe joint target, rad, inside the joint bounds (input of stage 6)."""
    kp: np.ndarray
    """(B, J) stiffness after torque pre-clipping, N m/rad."""
    kd: np.ndarray
    """(B, J) damping rho*sqrt(kp), N m s/rad."""
    rho: np.ndarray
    """(B, J) damping ratio (the pre-clip keeps it)."""
    tau_limit: np.ndarray
    """(B, J) torque bound for the executor's hard clip, N m."""
    dq: np.ndarray
    """(B, J) residual after stages 2-4, rad; zero where rejected."""
    rejected: np.ndarray
    """(B,) bool, the action was rejected and the environment holds its last safe target."""
    reason: np.ndarray
    """(B,) int8 `stages.Rejection` code, 0 where accepted."""
    reports: tuple[StageReport, ...]
    """Per stage, per environment: applied, clipped and excess."""
    schedule: ScheduleValues
    """xi and eps_x used for this step."""

    @property
    def stats(self) -> tuple[StageStats, ...]:
        """Per-stage summary of this call."""
        return tuple(summarize(report) for report in self.reports)

    def reasons(self) -> list[str]:
        """Rejection name per environment ("ACCEPTED" where accepted)."""
        return [stages.Rejection(code).name for code in self.reason]


def target_bounds(config: SafetyConfig) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi), each (J,): the joint band targets stay in (the full range if stage 5 is off)."""
    fraction = config.joint_limits.central_fraction if config.joint_limits.enabled else 1.0
    return stages.joint_target_bounds(fraction)


def tau_limit(config: SafetyConfig) -> np.ndarray:
    """(J,) torque bound of stage 7 and the executor: (1 - margin)*tau_max, N m."""
    return (1.0 - config.torque_preclip.margin) * FR3.tau_max


def initial_state(num_envs: int, config: SafetyConfig) -> SafetyState:
    """No targets yet, hold gains, empty EMA memory."""
    shape = (num_envs, NUM_JOINTS)
    return SafetyState(
        q_target=np.zeros(shape),
        kp=np.full(shape, config.nonfinite_guard.hold_kp),
        rho=np.full(shape, config.nonfinite_guard.hold_rho),
        dq_smoothed=np.zeros(shape),
        has_target=np.zeros(num_envs, dtype=bool),
    )


def start_episodes(
    state: SafetyState, start: np.ndarray, q: np.ndarray, config: SafetyConfig
) -> SafetyState:
    """New episodes in envs `start` (B,) bool: hold q (clipped into the bounds, or the home pose
    if q is non-finite) with hold gains, and clear the EMA memory."""
    lo, hi = target_bounds(config)
    hold = np.where(np.isfinite(q).all(axis=1)[:, None], q, Q_HOME)  # (B, J)
    column = start[:, None]
    return SafetyState(
        q_target=np.where(column, np.clip(hold, lo, hi), state.q_target),
        kp=np.where(column, config.nonfinite_guard.hold_kp, state.kp),
        rho=np.where(column, config.nonfinite_guard.hold_rho, state.rho),
        dq_smoothed=np.where(column, 0.0, state.dq_smoothed),
        has_target=state.has_target | start,
    )


def _check_state(name: str, array: np.ndarray, num_envs: int) -> np.ndarray:
    array = np.asarray(array, dtype=np.float64)
    if array.shape != (num_envs, NUM_JOINTS):
        raise ValueError(f"{name} must be ({num_envs}, {NUM_JOINTS}), got {array.shape}")
    return array


def filter_action(
    config: SafetyConfig,
    state: SafetyState,
    action: object,
    q: np.ndarray,
    dq: np.ndarray,
    step: int,
    jacobians: Jacobians,
    episode_start: np.ndarray | None = None,
    stale: np.ndarray | None = None,
) -> tuple[FilterResult, SafetyState]:
    """Stages 1-5 and 7 for one batch.

    Args:
        config: the stages' settings.
        state: per-env memory from the previous call (`initial_state` at first).
        action: raw policy action, expected (B, 21); anything else is rejected, not raised.
        q, dq: (B, J) measured joint positions (rad) and velocities (rad/s); rows with NaN/Inf
            are rejected (reason STATE); a wrong shape raises ValueError (a caller's bug).
        step: env_transitions (hamnet.runtime.counter) from the trainer (drives xi, eps_x).
        jacobians: q (N, J) -> (N, 6, J) paddle Jacobians (`Jacobians`), called once per
            batch where stage 2 ("paddle" space) or stage 3 needs them.
        episode_start: (B,) bool, envs starting an episode with this action (EMA cleared, hold
            target reset to q), or None.
        stale: (B,) bool, envs whose action was computed for another episode (rejected,
            reason EPISODE), or None.
    Returns:
        The FilterResult and the next SafetyState.
    """
    b = state.num_envs
    q, dq = _check_state("q", q, b), _check_state("dq", dq, b)  # (B, J)
    start = ~state.has_target
    if episode_start is not None:
        start = start | np.asarray(episode_start, dtype=bool)
    state = start_episodes(state, start, q, config)

    # Stage 1. Rows with a non-finite state are computed at rest on the held target.
    state_ok = np.isfinite(q).all(axis=1) & np.isfinite(dq).all(axis=1)  # (B,)
    q_now = np.where(state_ok[:, None], q, state.q_target)  # (B, J)
    dq_now = np.where(state_ok[:, None], dq, 0.0)
    raw, reason, report = _run_guard(config, action, state_ok, stale)  # (B, 21), (B,)
    accepted = reason == stages.Rejection.ACCEPTED  # (B,)
    reports = [report]

    # Stage 2: physical ranges and the annealed bound xi.
    values = schedule_values(step, config.action_magnitude, config.cartesian_clip)
    magnitude = config.action_magnitude
    xi = per_joint(values.xi_large, values.xi_small, magnitude.num_large_joints)  # (J,)
    needs_jacobian = magnitude.space == "paddle" or config.cartesian_clip.enabled
    jacobian = jacobians(q_now) if needs_jacobian else None  # (B, 6, J)
    dq_step, kp, rho, excess = stages.action_magnitude(raw, xi, magnitude, jacobian)  # (B, J) x3
    reports.append(stage_report("action_magnitude", accepted & magnitude.enabled, excess))

    # Stage 3.
    dq_step, report = _run_cartesian(config, dq_step, accepted, values.eps_x, jacobian)
    reports.append(report)

    # Stage 4: EMA of the residual, memory kept per env.
    smoothing = config.residual_smoothing
    alpha = smoothing.alpha if smoothing.enabled else 1.0
    dq_bar, excess = stages.residual_smoothing(dq_step, state.dq_smoothed, alpha)  # (B, J)
    reports.append(stage_report("residual_smoothing", accepted & smoothing.enabled, excess))

    # Stage 5: target inside the band; rejected envs hold their last safe target and gains.
    q_target, excess = q_now + dq_bar, np.zeros(b)  # (B, J)
    if config.joint_limits.enabled:
        q_target, excess = stages.joint_limits(q_target, *target_bounds(config))
    reports.append(stage_report("joint_limits", accepted & config.joint_limits.enabled, excess))
    column = accepted[:, None]
    q_target = np.where(column, q_target, state.q_target)  # (B, J)
    kp, rho = np.where(column, kp, state.kp), np.where(column, rho, state.rho)

    # Stage 7 against the target (recheck_torque repeats it against stage 6's samples).
    kp_safe, kd_safe, limit, report = _run_torque(config, q_target, q_now, dq_now, kp, rho)
    reports.append(report)

    result = FilterResult(
        q_target=q_target,
        kp=kp_safe,
        kd=kd_safe,
        rho=rho,
        tau_limit=limit,
        dq=np.where(column, dq_bar, 0.0),
        rejected=~accepted,
        reason=reason,
        reports=tuple(reports),
        schedule=values,
    )
    next_state = dataclasses.replace(
        state,
        q_target=q_target,
        kp=kp,
        rho=rho,
        dq_smoothed=np.where(column, dq_bar, state.dq_smoothed),
    )
    return result, next_state


def _run_guard(
    config: SafetyConfig, action: object, state_ok: np.ndarray, stale: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, StageReport]:
    """Stage 1: cleaned action (B, 21), reason (B,) (STATE where the state is non-finite,
    EPISODE where the action belongs to another episode)."""
    b = state_ok.shape[0]
    if not config.nonfinite_guard.enabled:
        array = np.asarray(action, dtype=np.float64)
        if array.shape != (b, stages.ACTION_DIM):
            raise ValueError(f"action must be ({b}, {stages.ACTION_DIM}), got {array.shape}")
        reason = np.zeros(b, dtype=np.int8)
        return array, reason, stage_report("nonfinite_guard", np.zeros(b, bool), np.zeros(b))
    raw, reason = stages.nonfinite_guard(action, b)
    if stale is not None:
        stale = np.asarray(stale, dtype=bool) & (reason == stages.Rejection.ACCEPTED)  # (B,)
        reason[stale] = stages.Rejection.EPISODE
        raw[stale] = 0.0
    reason[~state_ok] = stages.Rejection.STATE
    rejected = (reason != stages.Rejection.ACCEPTED).astype(np.float64)  # 1 per rejection
    return raw, reason, stage_report("nonfinite_guard", np.ones(b, bool), rejected)


def _run_cartesian(
    config: SafetyConfig,
    dq: np.ndarray,
    accepted: np.ndarray,
    eps_x: float,
    jacobian: np.ndarray | None,
) -> tuple[np.ndarray, StageReport]:
    """Stage 3 on the accepted envs only; `jacobian` (B, 6, J) at the measured posture, set
    when the stage is enabled."""
    cartesian = config.cartesian_clip
    applied = accepted & cartesian.enabled  # (B,)
    excess = np.zeros(dq.shape[0])
    if applied.any():
        dq = dq.copy()
        rows = jacobian[applied][:, JACOBIAN_ROWS[cartesian.rows]]  # (N, R, J)
        dq[applied], excess[applied] = cartesian_clip(
            dq[applied], rows, eps_x, cartesian.damping, cartesian.iterations
        )
    return dq, stage_report("cartesian_clip", applied, excess)


def _run_torque(
    config: SafetyConfig,
    q_target: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    kp: np.ndarray,
    rho: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, StageReport]:
    """Stage 7 for every env (holds included): kp, kd, tau_limit (B, J) and the report."""
    b = q.shape[0]
    limit = np.tile(tau_limit(config), (b, 1))  # (B, J)
    if not config.torque_preclip.enabled:
        off = stage_report("torque_preclip", np.zeros(b, bool), np.zeros(b))
        return kp, stages.damping_gain(kp, rho), limit, off
    kp, kd, excess = stages.torque_preclip(q_target, q, dq, kp, rho, limit)
    return kp, kd, limit, stage_report("torque_preclip", np.ones(b, bool), excess)


def recheck_torque(
    config: SafetyConfig, result: FilterResult, q_ref: np.ndarray, q: np.ndarray, dq: np.ndarray
) -> FilterResult:
    """Stage 7 again, against stage 6's reference samples q_ref (B, S, J): gains only go down.

    Non-finite state rows are checked at rest on the target, as in `filter_action`. The
    result's torque_preclip report then covers both passes (excess: the larger one).
    """
    if not config.torque_preclip.enabled:
        return result
    state_ok = (np.isfinite(q).all(axis=1) & np.isfinite(dq).all(axis=1))[:, None]  # (B, 1)
    q_now, dq_now = np.where(state_ok, q, result.q_target), np.where(state_ok, dq, 0.0)
    kp, kd, excess = stages.torque_preclip(
        q_ref, q_now, dq_now, result.kp, result.rho, result.tau_limit
    )
    reports = tuple(
        stage_report(r.stage, r.applied, np.maximum(r.excess, excess))
        if r.stage == "torque_preclip"
        else r
        for r in result.reports
    )
    return dataclasses.replace(result, kp=kp, kd=kd, reports=reports)


class SafetyCore:
    """Stateful wrapper for the shell and the trainer: per-env memory, Pinocchio model, stats."""

    def __init__(self, num_envs: int, config: SafetyConfig | None = None) -> None:
        self.config = config if config is not None else SafetyConfig()
        self.state = initial_state(num_envs, self.config)
        self.stats = StatsAccumulator()
        """Running per-stage statistics; the shell publishes `summary()` and resets them."""
        self._model, self._data = load_pinocchio()

    def jacobians(self, q: np.ndarray) -> np.ndarray:
        """(N, 6, J) paddle Jacobians at q (N, J) (`Jacobians`)."""
        return ee_jacobians(self._model, self._data, q, "full")

    def reset(self, q: np.ndarray, env_ids: np.ndarray | None = None) -> None:
        """Start episodes in `env_ids` (all if None) at joint positions q (B, J)."""
        start = np.zeros(self.state.num_envs, dtype=bool)
        start[slice(None) if env_ids is None else np.asarray(env_ids)] = True
        q = _check_state("q", q, self.state.num_envs)
        self.state = start_episodes(self.state, start, q, self.config)

    def filter(
        self,
        action: object,
        q: np.ndarray,
        dq: np.ndarray,
        step: int,
        episode_start: np.ndarray | None = None,
        record: bool = True,
        stale: np.ndarray | None = None,
    ) -> FilterResult:
        """Stages 1-5 and 7 (see `filter_action`); updates the memory, and the statistics
        unless `record` is False (a caller that runs `recheck_torque` records afterwards)."""
        result, self.state = filter_action(
            self.config, self.state, action, q, dq, step, self.jacobians, episode_start, stale
        )
        if record:
            self.record(result)
        return result

    def recheck_torque(
        self, result: FilterResult, q_ref: np.ndarray, q: np.ndarray, dq: np.ndarray
    ) -> FilterResult:
        """Stage 7 against stage 6's samples q_ref (B, S, J) (see `recheck_torque`)."""
        return recheck_torque(self.config, result, q_ref, q, dq)

    def snapshot(self) -> dict[str, np.ndarray]:
        """Copies of the per-environment memory (`SafetyState` fields), to continue from with
        `restore`. The running statistics are left out: they report, never act."""
        return {f.name: getattr(self.state, f.name).copy() for f in dataclasses.fields(SafetyState)}

    def restore(self, arrays: dict[str, np.ndarray]) -> None:
        """Continue from `snapshot`'s arrays."""
        fields = dataclasses.fields(SafetyState)
        self.state = SafetyState(**{f.name: np.array(arrays[f.name]) for f in fields})

    def record(self, result: FilterResult) -> None:
        """Add a result's per-stage reports to the running statistics."""
        self.stats.add(result.reports)
