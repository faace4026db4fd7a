"""Stage 6 of the deploy profile: jerk-limited joint references with Ruckig, sampled for one
policy period (the config and output types are in `references`).

Consumes one joint target per environment and policy period (already clipped into the joint
range by stage 5); produces the reference the executor tracks until the next action: q_ref and
dq_ref at the control rate (S samples per period: 8 at 80 Hz in sim, 100 at 1 kHz on the real
FR3), within the FR3's dq_max, ddq_max and jerk_max scaled by a dynamics factor.

Each period plans from the reference state where the previous period ended (position, velocity
and acceleration, so nothing jumps at period boundaries) to the target at rest, with one Ruckig
instance per environment, and samples that plan for one period only. A target not reached within
the period is simply planned again next period from where the reference is. Sample k of a period
is the plan at time (k + 1) * dt: the last sample is the state the next period starts from.

Ruckig (community edition) ignores position limits, and a plan from a moving state to a nearby
target may overshoot it. The generator keeps every plan it follows inside the joint range (the
start position counts as inside): it checks the whole plan's position extrema (computed here
from the plan's polynomials, as ruckig 0.19.4's are often wrong) and otherwise brakes for this
period, each joint stopping time-optimally. Every plan followed ends at rest inside the range,
and braking as hard as the limits allow from a point of it comes to rest no further out, so
the brake stays inside too. In 31k random moving states (both dynamics factors) whose brake
stayed inside, no plan to a target inside the range left it: the guard is a proof obligation,
not a common path; it is reported as `Plan.STOP_RANGE` when it acts.
"""

from __future__ import annotations

import numpy as np
import ruckig

from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.safety.references import (
    Plan,
    References,
    ReferenceState,
    Stoppable,
    TrajectoryConfig,
    joint_rows,
)


class TrajectoryGenerator(Stoppable):
    """Batched jerk-limited reference generator: one Ruckig instance per environment.

    Holds each environment's reference state between calls; `step` advances all of them by one
    policy period. Environments told to `stop` brake to rest and hold until `resume` or `reset`.
    """

    def __init__(self, q: np.ndarray, config: TrajectoryConfig | None = None) -> None:
        """Start every environment at rest.

        Args:
            q: start positions, (B, J), rad (measured, so not clipped).
            config: limits and clocks; the defaults when None.
        """
        self.config = config if config is not None else TrajectoryConfig()
        q = joint_rows(q)  # (B, J)
        self.num_envs = q.shape[0]
        cfg = self.config
        self._q_min = np.asarray(cfg.limits.q_min, dtype=np.float64)  # (J,)
        self._q_max = np.asarray(cfg.limits.q_max, dtype=np.float64)  # (J,)
        self._times = [cfg.control_period_s * (k + 1) for k in range(cfg.samples_per_period)]
        self._times[-1] = cfg.policy_period_s  # the period's end exactly
        self._times_array = np.array(self._times)  # (S,), s
        self._ruckig = [ruckig.Ruckig(J) for _ in range(self.num_envs)]
        self._inputs = [_input_parameter(cfg) for _ in range(self.num_envs)]
        self._trajectories = [ruckig.Trajectory(J) for _ in range(self.num_envs)]
        self._q = q.copy()  # (B, J), rad
        self._dq = np.zeros_like(q)  # (B, J), rad/s
        self._ddq = np.zeros_like(q)  # (B, J), rad/s^2
        self._stopping = np.zeros(self.num_envs, dtype=bool)  # (B,)

    @property
    def state(self) -> ReferenceState:
        """Where the next period starts, (B, J) each (copies)."""
        return ReferenceState(self._q.copy(), self._dq.copy(), self._ddq.copy())

    def reset(
        self,
        env_ids: np.ndarray,
        q: np.ndarray,
        dq: np.ndarray | None = None,
        ddq: np.ndarray | None = None,
    ) -> None:
        """Re-anchor environments at a measured state, at rest by default (episode start).

        Args:
            env_ids: environment indices, (N,) int, or a (B,) bool mask selecting N.
            q: measured positions, (N, J), rad; not clipped (the reference must start where
                the robot is); plans from outside the range head straight back inside.
            dq, ddq: measured velocities (rad/s) and accelerations (rad/s^2), (N, J), within
                the scaled limits; zero when None.
        """
        q = joint_rows(q)  # (N, J)
        self._q[env_ids] = q
        self._dq[env_ids] = 0.0 if dq is None else joint_rows(dq)
        self._ddq[env_ids] = 0.0 if ddq is None else joint_rows(ddq)
        self._stopping[env_ids] = False

    def step(self, q_target: np.ndarray) -> References:
        """Plan from the current reference state to each target and sample one policy period.

        Args:
            q_target: joint targets, (B, J), rad, reached at rest; clipped into the joint range
                (less `target_margin`) as a last guard. Ignored for stopping environments;
                a non-finite row makes that environment brake and hold for this period.
        Returns:
            the references (B, S, J) with the plan and Ruckig result per environment; the
            generator's state moves to their last sample.
        """
        q_target = np.asarray(q_target, dtype=np.float64)
        if q_target.shape != (self.num_envs, J):
            raise ValueError(f"q_target must be ({self.num_envs}, {J}), got {q_target.shape}")
        target = self._clip_target(q_target)  # (B, J), rad (NaN stays NaN)
        plan = np.where(self._stopping, Plan.STOP, Plan.TARGET).astype(np.int8)  # (B,)
        result = np.zeros(self.num_envs, dtype=np.int64)  # (B,)
        for i in np.flatnonzero(plan == Plan.TARGET):
            result[i] = self._plan_target(i, target[i])
        plan[result < 0] = Plan.STOP_INVALID_TARGET
        planned = np.flatnonzero(plan == Plan.TARGET)  # (N,)
        plan[planned[~self._in_range(planned)]] = Plan.STOP_RANGE
        samples = np.empty((self.num_envs, len(self._times), 3, J))  # (B, S, [q, dq, ddq], J)
        reached = np.ones(self.num_envs, dtype=bool)  # (B,)
        for i in range(self.num_envs):
            if plan[i] != Plan.TARGET and not self._plan_stop(i):
                plan[i] = Plan.HOLD
                samples[i] = 0.0
                samples[i, :, 0] = self._q[i]
                continue
            samples[i], reached[i] = self._sample(self._trajectories[i])
        self._q, self._dq, self._ddq = (samples[:, -1, k].copy() for k in range(3))
        return References(
            q_ref=samples[:, :, 0],
            dq_ref=samples[:, :, 1],
            ddq_ref=samples[:, :, 2],
            plan=plan,
            result=result,
            reached=reached,
        )

    def _clip_target(self, q_target: np.ndarray) -> np.ndarray:
        """Targets inside the joint range less the margin, (B, J), rad; NaN passes through."""
        margin = self.config.target_margin
        return np.clip(q_target, self._q_min + margin, self._q_max - margin)

    def _set_current(self, i: int) -> ruckig.InputParameter:
        """The env's Ruckig input, starting from its reference state."""
        inp = self._inputs[i]
        inp.current_position = self._q[i].tolist()
        inp.current_velocity = self._dq[i].tolist()
        inp.current_acceleration = self._ddq[i].tolist()
        return inp

    def _plan_target(self, i: int, target: np.ndarray) -> int:
        """Ruckig's plan to `target` at rest, joints phase-synchronised (a straight line in
        joint space where possible, else time-synchronised); its Result as int."""
        if not np.all(np.isfinite(target)):
            return int(ruckig.Result.ErrorInvalidInput)
        inp = self._set_current(i)
        inp.control_interface = ruckig.ControlInterface.Position
        inp.synchronization = ruckig.Synchronization.Phase
        inp.target_position = target.tolist()
        return _calculate(self._ruckig[i], inp, self._trajectories[i])

    def _plan_stop(self, i: int) -> bool:
        """Ruckig's time-optimal stop of each joint (velocity interface to rest, joints not
        synchronised, so none brakes later than it can); whether a plan was found."""
        inp = self._set_current(i)
        inp.control_interface = ruckig.ControlInterface.Velocity
        inp.synchronization = ruckig.Synchronization.No
        return _calculate(self._ruckig[i], inp, self._trajectories[i]) >= 0

    def _in_range(self, env_ids: np.ndarray) -> np.ndarray:
        """Whether each env's whole planned trajectory stays inside the joint range (widened
        to include its start, for references re-anchored outside it), (N,) bool."""
        low, high = position_extrema([self._trajectories[i] for i in env_ids])  # (N, J) each
        q = self._q[env_ids]  # (N, J), rad
        low_ok = np.all(low >= np.minimum(self._q_min, q), axis=1)  # (N,)
        return low_ok & np.all(high <= np.maximum(self._q_max, q), axis=1)

    def _sample(self, trajectory: ruckig.Trajectory) -> tuple[np.ndarray, bool]:
        """The plan at the period's sample times, (S, 3, J), and whether it ends in the period."""
        samples = np.array([trajectory.at_time(t) for t in self._times])  # (S, 3, J)
        # After the plan's end Ruckig extrapolates rounding residue (|dq| ~ 1e-16); a reference
        # at rest is exactly at rest, or the next plan from it may fail (a Ruckig error
        # was seen for a zero-length move with such velocities).
        samples[self._times_array >= trajectory.duration, 1:] = 0.0
        return samples, trajectory.duration <= self._times[-1]


def position_extrema(trajectories: list[ruckig.Trajectory]) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest position of each joint over whole Ruckig plans, from their profiles.

    Ruckig's own `Trajectory.position_extrema` is not used: in ruckig 0.19.4 it misses interior
    extrema (wrong for about half of random one-joint plans from moving states). Each joint's
    plan is two brake phases then seven phases of constant jerk, then rest; a phase's extremum
    is at one of its ends or where its velocity v + a t + j t^2 / 2 crosses zero.

    Args:
        trajectories: N plans without intermediate waypoints (one section each).
    Returns:
        low and high, (N, J) each, rad.
    """
    duration, p, v, a, j = _phases(trajectories)  # (N, J, 9) each
    disc = np.sqrt(np.maximum(a * a - 2.0 * j * v, 0.0))  # (N, J, 9)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        roots = np.stack([(-a - disc) / j, (-a + disc) / j, -v / a], axis=-1)  # (N, J, 9, 3), s
    roots[..., :2][j == 0.0] = np.nan  # the quadratic's roots hold only with jerk,
    roots[..., 2][j != 0.0] = np.nan  # -v/a only without
    inside = (roots > 0.0) & (roots < duration[..., None])  # (N, J, 9, 3)
    t = np.where(inside, roots, 0.0)  # (N, J, 9, 3), s
    p_t = p[..., None] + (v[..., None] + (a[..., None] / 2 + j[..., None] * t / 6) * t) * t
    p_end = p + (v + (a / 2 + j * duration / 6) * duration) * duration  # (N, J, 9), rad
    candidates = np.concatenate([p[..., None], p_end[..., None], p_t], axis=-1)  # (N, J, 9, 5)
    # Phases that do not occur (zero duration; Ruckig leaves an unused brake at zeros) must
    # not count: they take the value of the main profile's start, a point of the plan.
    candidates = np.where(duration[..., None] > 0.0, candidates, p[..., 2:3, None])
    return candidates.min(axis=(2, 3)), candidates.max(axis=(2, 3))


def _phases(trajectories: list[ruckig.Trajectory]) -> tuple[np.ndarray, ...]:
    """Duration, start position, velocity, acceleration and jerk of each joint's nine phases
    (two brake, seven main), (N, J, 9) each; an unused brake is all zeros."""
    flat: list[float] = []  # per profile: t (7), p (8), v (8), a (8), j (7)
    brakes = []  # (row, [t, p, v, a, j] of 2 each), only where a brake is planned
    for trajectory in trajectories:
        for profile in trajectory.profiles[0]:
            if profile.brake.duration > 0.0:
                brake = profile.brake
                brakes.append((len(flat) // 38, [brake.t, brake.p, brake.v, brake.a, brake.j]))
            flat += profile.t
            flat += profile.p
            flat += profile.v
            flat += profile.a
            flat += profile.j
    main = np.array(flat, dtype=np.float64).reshape(-1, 38)  # (N * J, 38)
    phases = np.zeros((5, main.shape[0], 9))  # ([t, p, v, a, j], N * J, 9)
    for k, begin in enumerate((0, 7, 15, 23, 31)):
        phases[k, :, 2:] = main[:, begin : begin + 7]
    for row, values in brakes:
        phases[:, row, :2] = values
    return tuple(phases[k].reshape(-1, J, 9) for k in range(5))  # (N, J, 9) each


def _input_parameter(config: TrajectoryConfig) -> ruckig.InputParameter:
    """Ruckig input with the scaled limits and a target at rest."""
    inp = ruckig.InputParameter(J)
    inp.max_velocity = config.dq_max.tolist()
    inp.max_acceleration = config.ddq_max.tolist()
    inp.max_jerk = config.jerk_max.tolist()
    inp.target_velocity = [0.0] * J
    inp.target_acceleration = [0.0] * J
    return inp


def _calculate(
    generator: ruckig.Ruckig, inp: ruckig.InputParameter, trajectory: ruckig.Trajectory
) -> int:
    """Ruckig's offline calculation; its Result as int, exceptions as ErrorInvalidInput."""
    try:
        return int(generator.calculate(inp, trajectory))
    except ruckig.RuckigError:
        return int(ruckig.Result.ErrorInvalidInput)
