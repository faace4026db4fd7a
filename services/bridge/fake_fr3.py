"""A strict fake FR3 controller: the robot behind the bridge's `fake` driver, which refuses
commanded references the way libfranka's FCI does (`hamnet.fr3.reflexes`).

Consumes commanded joint positions (and, where the executor sends them, joint torques) at the
robot's 1 kHz control period, one block of ticks per call, for one robot or a batch; produces,
per robot, whether the block was executed and, at the first offending tick, the reflex errors
under libfranka's `franka::Errors` names. A robot in reflex refuses every command until
`recover()`, as the real one does until `automaticErrorRecovery()`.

Before the first command the robot is at rest at its start position with zero commanded torque,
so the differences of the first ticks use that history (a motion must start from rest).
Differentiated checks allow `relative_tolerance` above each limit for float64 rounding; the
position check allows nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.fr3.limits import FR3Limits
from hamnet.fr3.reflexes import REFLEXES, reflex_flags


@dataclass(frozen=True)
class FakeFR3Config:
    """Clock, limits and strictness of the fake controller."""

    control_period_s: float = 1e-3
    """dt of the commanded references, s (libfranka's kDeltaT: 1 kHz)."""
    relative_tolerance: float = 1e-6
    """Differentiated quantities may exceed their limit by this fraction: float64 rounding of a
    third difference at 1 kHz is about 1e-5 rad/s^3 (2e-9 of jerk_max), while libfranka's own
    rate limiter keeps 1e-3 below each limit (kLimitEps)."""
    raise_on_reflex: bool = False
    """Raise `ReflexError` from `command` when a robot enters reflex (else only record it)."""
    limits: FR3Limits = field(default_factory=FR3Limits)
    """The robot's limits (Franka's FR3 control-parameter table)."""

    def __post_init__(self) -> None:
        if self.control_period_s <= 0.0 or not 0.0 <= self.relative_tolerance < 0.1:
            raise ValueError("control_period_s must be > 0 and relative_tolerance in [0, 0.1)")


class ReflexError(RuntimeError):
    """Robots entered reflex; `errors` maps each robot index to its reflex names."""

    def __init__(self, errors: dict[int, frozenset[str]]) -> None:
        self.errors = errors
        text = "; ".join(f"robot {i}: {', '.join(sorted(names))}" for i, names in errors.items())
        super().__init__(f"reflex: {text}")


class FakeFR3:
    """Strict fake of the FR3's controller for one robot or a batch.

    Batched: built from (B, J) start positions, `command` takes (B, S, J) blocks. Single robot:
    built from (J,), `command` takes (S, J) and returns a bool. Properties are always batched.
    """

    def __init__(self, q: np.ndarray, config: FakeFR3Config | None = None) -> None:
        """The robots stand still at their start positions.

        Args:
            q: measured start positions, (B, J) or (J,), rad.
            config: clock and limits; the defaults when None.
        """
        self.config = config if config is not None else FakeFR3Config()
        q = np.array(q, dtype=np.float64)
        self.single = q.ndim == 1
        q = np.atleast_2d(q)  # (B, J)
        if q.ndim != 2 or q.shape[1] != J or not np.all(np.isfinite(q)):
            raise ValueError(f"start positions must be finite, (B, {J}) or ({J},)")
        self.num_robots = q.shape[0]
        self._q_history = np.repeat(q[:, None], 3, axis=1)  # (B, 3, J), rad, newest last
        self._tau_last = np.zeros_like(q)  # (B, J), N m
        self._fresh = np.ones(self.num_robots, dtype=bool)  # (B,) no tick since (re)start
        self._errors: list[frozenset[str]] = [frozenset()] * self.num_robots
        self.ticks = np.zeros(self.num_robots, dtype=np.int64)
        """Ticks executed per robot, (B,)."""
        self.refused = np.zeros(self.num_robots, dtype=np.int64)
        """Commands refused per robot because it was in reflex, (B,)."""
        self.reflex_tick = np.full(self.num_robots, -1, dtype=np.int64)
        """Tick (count since construction) that triggered the current reflex, (B,); -1: none."""

    @property
    def q(self) -> np.ndarray:
        """Last executed commanded position (the robot's position), (B, J), rad (a copy)."""
        return self._q_history[:, -1].copy()

    @property
    def errors(self) -> tuple[frozenset[str], ...]:
        """Reflex names per robot, (B,) of sets; empty while the robot accepts commands."""
        return tuple(self._errors)

    @property
    def in_reflex(self) -> np.ndarray:
        """Robots refusing commands until `recover`, (B,) bool."""
        return np.array([bool(names) for names in self._errors])

    def command(self, q_ref: np.ndarray, tau: np.ndarray | None = None) -> np.ndarray | bool:
        """Execute a block of commanded ticks, up to the first one that triggers a reflex.

        Args:
            q_ref: commanded positions, (B, S, J) (single robot: (S, J)), rad, one per dt.
            tau: commanded torques, same shape, N m; None when the executor sends none.
        Returns:
            whether each robot executed the whole block, (B,) bool (single robot: a bool).
        Raises:
            ReflexError: a robot entered reflex and `raise_on_reflex` is set.
        """
        q_ref = self._as_block(q_ref)  # (B, S, J)
        tau = None if tau is None else self._as_block(tau)  # (B, S, J)
        cfg = self.config
        q = np.concatenate([self._q_history, q_ref], axis=1)  # (B, 3 + S, J)
        tau_all = None if tau is None else np.concatenate([self._tau_last[:, None], tau], axis=1)
        flags = reflex_flags(
            q, tau_all, cfg.limits, cfg.control_period_s, cfg.relative_tolerance, self._fresh
        )  # (B, S, R)
        offending = flags.any(axis=2)  # (B, S)
        S = q_ref.shape[1]
        active = ~self.in_reflex  # (B,)
        executed = np.where(offending.any(axis=1), offending.argmax(axis=1), S)  # (B,)
        executed[~active] = 0
        self._advance(q, tau_all, executed)
        new_reflexes = {}
        for i in np.flatnonzero(active & (executed < S)):
            names = frozenset(n for n, hit in zip(REFLEXES, flags[i, executed[i]]) if hit)
            self._errors[i] = names
            self.reflex_tick[i] = self.ticks[i]
            new_reflexes[int(i)] = names
        self.refused += ~active
        if new_reflexes and cfg.raise_on_reflex:
            raise ReflexError(new_reflexes)
        accepted = active & (executed == S)  # (B,)
        return bool(accepted[0]) if self.single else accepted

    def recover(self, robot_ids: np.ndarray | None = None, q: np.ndarray | None = None) -> None:
        """Clear reflexes; the robots stand still (at `q`, or where they stopped).

        Args:
            robot_ids: robots to recover, (N,) int or (B,) bool; all when None.
            q: measured positions to restart from, (N, J), rad; None: last executed command.
        """
        ids = np.arange(self.num_robots) if robot_ids is None else np.asarray(robot_ids)
        ids = np.flatnonzero(ids) if ids.dtype == bool else ids
        rest = self._q_history[ids, -1] if q is None else np.asarray(q, dtype=np.float64)
        self._q_history[ids] = np.reshape(rest, (len(ids), 1, J))
        self._tau_last[ids] = 0.0
        self._fresh[ids] = True
        self.reflex_tick[ids] = -1
        for i in ids:
            self._errors[i] = frozenset()

    def _as_block(self, values: np.ndarray) -> np.ndarray:
        """Commanded values as (B, S, J) float64, or ValueError."""
        values = np.asarray(values, dtype=np.float64)
        if self.single:
            values = values[None] if values.ndim == 2 else values[None, None]
        if values.ndim != 3 or values.shape[0] != self.num_robots or values.shape[2] != J:
            raise ValueError(f"commands must be (B={self.num_robots}, S, {J}), got {values.shape}")
        return values

    def _advance(self, q: np.ndarray, tau: np.ndarray | None, executed: np.ndarray) -> None:
        """Keep the history up to each robot's last executed tick.

        Args:
            q: history then the block, (B, 3 + S, J); tau: (B, 1 + S, J) or None.
            executed: ticks executed per robot, (B,).
        """
        window = executed[:, None] + np.arange(3)  # (B, 3): the last three executed
        self._q_history = np.take_along_axis(q, window[:, :, None], axis=1)  # (B, 3, J)
        if tau is not None:
            self._tau_last = np.take_along_axis(tau, executed[:, None, None], axis=1)[:, 0]
        self.ticks += executed
        self._fresh &= executed == 0
