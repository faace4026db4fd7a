"""The safety loop without a network: which state gets which command, and when.

Consumes decoded robot states (`StateIn`), policy actions (`ActionIn`), the trainer's
env_transitions and the e-stop latch's requests; produces `SafeAnswer`s (state k's safe
command, step k, as the sim's lock-step requires) and `Notice`s (the events: watchdog and
e-stop events here; rejections, rate-limited clip events and per-stage statistics every
`stats_period_s` from `hamnet.safety.reports`), handed to an injected `emit` in the order
they happen. Time comes from an
injected `clock` (time.monotonic in the service), so a test drives every wait with a fake
clock and no Zenoh.

State k waits for action k (an action is used only for the state it answers) up to
`watchdog_s` after the oldest state still unanswered (a real-time executor sends newer
states meanwhile; each replaces the one waiting). Without it the watchdog brakes every
environment (one WATCHDOG_STOP event) and every later state is answered at once with the
brake, until an action arrives again (any step: the policy is alive), when the filter
resumes from the measured joint positions and the next state waits for its action again.
While the e-stop is latched, actions are ignored and every state gets the brake. Braking
commands are paced at about the policy period (`BRAKE_PACE`), so a lock-step sim stays near
real time while no policy drives it.
A state of another run of the sim (`Header.run`: the sim restarted) starts every
environment's episode afresh in the filter (a new sim may reuse the old episode ids) and
forgets the old run's answer and action; a state implausibly far ahead of the newest one
(`hamnet.runtime.freshness`) is dropped, so a forged step cannot supersede the real one.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np

from hamnet.messages.action import ActionIn
from hamnet.messages.robot_state import StateIn
from hamnet.runtime.freshness import Verdict, Watermark
from hamnet.runtime.shell_config import Flattened, ReportConfig
from hamnet.safety.config import SafetyConfig
from hamnet.safety.estop import EStop
from hamnet.safety.filter import SafeOutput, SafetyFilter
from hamnet.safety.references import TrajectoryConfig
from hamnet.safety.reports import Notice, Reports

log = logging.getLogger(__name__)

BRAKE_PACE = 0.9
"""While stopped, states are answered at once but at most one per this share of the policy
period: a lock-step sim would otherwise run flat out while the arm is held, and a real-time
executor sends one state per period anyway (the 10% absorbs its jitter)."""


@dataclass(frozen=True)
class SafeAnswer:
    """The safe command answering state `step`."""

    output: SafeOutput
    step: int
    episode_ids: np.ndarray
    """(B,) the state's episodes, echoed so the executor can match the command to them."""


def episode_starts(state: StateIn, previous_ids: np.ndarray | None) -> np.ndarray:
    """(K,) environments whose episode starts in this state: step 0 or a new episode id."""
    new = state.episode_step == 0  # (B,)
    if previous_ids is not None:
        new |= state.episode_ids != previous_ids
    return np.flatnonzero(new)


@dataclass(frozen=True)
class SafetyLoopConfig:
    """Batch size, watchdog and reporting of the safety loop."""

    num_envs: int = 0
    """B, environments per state; 0 takes it from the first state."""
    watchdog_s: float = 0.3
    """Longest wait for the action of a state, s; then every environment brakes to rest."""
    clip_event_period_s: float = 1.0
    """At most one clip event per stage this often, s (it counts what happened since)."""
    stats_period_s: float = 5.0
    """Seconds between per-stage statistics events."""
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)

    def __post_init__(self) -> None:
        if self.num_envs < 0:
            raise ValueError(f"num_envs must be >= 0, got {self.num_envs}")
        if not self.watchdog_s > 0.0:
            raise ValueError(f"watchdog_s must be > 0, got {self.watchdog_s}")


class Supervisor:
    """The filter, the pending state, the watchdog and the e-stop's effect on one worker."""

    def __init__(
        self,
        emit: Callable[[SafeAnswer | Notice], None],
        config: SafetyLoopConfig | None = None,
        safety: SafetyConfig | None = None,
        trajectory: TrajectoryConfig | None = None,
        estop: EStop | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.emit, self.clock = emit, clock
        self.config = config if config is not None else SafetyLoopConfig()
        self.safety = safety if safety is not None else SafetyConfig()
        self.trajectory = trajectory if trajectory is not None else TrajectoryConfig()
        self.estop = estop if estop is not None else EStop()
        self.num_envs: int | None = self.config.num_envs or None
        self.filter: SafetyFilter | None = None
        self.env_transitions = 0
        """The trainer's counter, which the annealing of xi and eps_x follows."""
        self.latest: StateIn | None = None
        """The newest state received."""
        self.pending: StateIn | None = None
        """A state waiting for its action, with `deadline` (on `clock`)."""
        self.deadline = 0.0
        self.received_at = 0.0
        """When the pending state arrived (on `clock`)."""
        self.brake_at = 0.0
        """While stopped: when the pending state gets its brake (paced, see BRAKE_PACE)."""
        self.last_command_at = -np.inf
        """When the last command was emitted (on `clock`)."""
        self.action: ActionIn | None = None
        """The newest action not used yet."""
        self.policy_heard = False
        """Whether any action has arrived yet (before that, a stop is the expected wait for
        a policy still starting, not a policy gone silent)."""
        self.stopped_by: str | None = None
        """None (following the policy), "watchdog" or "estop"."""
        self.answered: SafeAnswer | None = None
        """The last command sent, sent again when the sim sends its state again."""
        self.reports = Reports(
            emit,
            clock,
            self.config.clip_event_period_s,
            self.config.stats_period_s,
            self.config.report.report_period_s,
        )
        self.watermark = Watermark()
        """The sim's run and its newest state: a restart is followed, a step implausibly
        far ahead is dropped."""

    @property
    def period(self) -> float:
        """The policy period, s."""
        return self.trajectory.policy_period_s

    def due(self) -> float | None:
        """When the pending state must be acted on (on `clock`): the watchdog's deadline, or
        the next brake while stopped; None without a pending state."""
        if self.pending is None:
            return None
        return self.deadline if self.stopped_by is None else self.brake_at

    def tick(self) -> None:
        """What is due by now: the watchdog, a paced brake, statistics and the rate line."""
        self._check_watchdog()
        self._answer()
        step = self.latest.step if self.latest is not None else 0
        every = np.arange(self.num_envs or 0)
        self.reports.periodic(step, every, self.stopped_by, self.env_transitions)

    # --- inputs ---------------------------------------------------------------------------

    def on_state(self, state: StateIn, received: float | None = None) -> None:
        """State k, `received` when it arrived (on `clock`; None: now)."""
        verdict = self.watermark.judge(state.run, state.step)
        if verdict is Verdict.IMPLAUSIBLE:
            self.reports.counts["implausible"] += 1  # a forged or corrupt step must not supersede
            return
        if verdict is Verdict.RESTART and self.watermark.restart(state.run):
            self._follow_new_run(state)
        self.watermark.advance(state.step)
        # The sim sends a state again while it waits for its command.
        if self.pending is not None and self.pending.step == state.step:
            return  # still waiting: the first arrival's deadline holds
        if self.answered is not None and self.answered.step == state.step and self.pending is None:
            self.emit(self.answered)  # answered already: the same answer again
            return
        if self.filter is None:
            self.num_envs = len(state.q)
            self.filter = SafetyFilter(state.q, self.safety, self.trajectory)
            log.info("%d environments, first state %d", self.num_envs, state.step)
            if self.stopped_by is not None:  # e-stop latched before the first state
                self.filter.stop(np.arange(self.num_envs))
        else:
            self._start_episodes(state)
        now = self.clock()
        received = now if received is None else min(received, now)
        if self.pending is None:
            self.deadline = received + self.config.watchdog_s
        else:  # a real-time executor moved on: the wait runs from the oldest unanswered state
            self.reports.counts["superseded"] += 1
        self.latest, self.pending, self.received_at = state, state, received
        self.brake_at = max(self.received_at, self.last_command_at + BRAKE_PACE * self.period)
        self._answer()

    def on_action(self, action: ActionIn) -> None:
        """The policy's action for state `action.step`."""
        self.policy_heard = True
        if self.estop.latched:
            self.reports.counts["ignored"] += 1
            return
        if self.latest is not None and action.step < self.latest.step:
            self.reports.counts["stale"] += 1
        if self.stopped_by == "watchdog" and self.latest is not None:
            self._resume("actions arrive again")
        self.action = action
        self._answer()

    def apply_estop(self) -> None:
        """Apply the latch's queued requests and publish the status its answers report."""
        for request in self.estop.take():
            step = self.latest.step if self.latest is not None else 0
            if request == "stop":
                log.warning("e-stop latched at step %d: braking every environment", step)
                self.stopped_by = "estop"
                if self.filter is not None:
                    self.filter.stop(np.arange(self.num_envs))
                self._notice("ESTOP_LATCHED", step, "e-stop", "stop requested")
            elif request == "reset" and self.stopped_by == "estop":
                self._resume("e-stop reset")
                self._notice("ESTOP_RESET", step, "e-stop", "reset requested")
        self.estop.status = {
            "step": self.latest.step if self.latest is not None else None,
            "stopped_by": self.stopped_by,
        }
        self._answer()

    def _follow_new_run(self, state: StateIn) -> None:
        """The sim restarted: nothing of its old run applies to the new one."""
        log.warning(
            "the sim restarted (another run) at step %d: every episode starts afresh", state.step
        )
        self.reports.counts["restarts"] += 1
        self.answered, self.pending, self.action = None, None, None
        if self.filter is not None and len(state.q) == self.num_envs:
            every = np.arange(self.num_envs)
            self.filter.start_episodes(every, state.q)
            if self.stopped_by is not None:  # a restart does not lift a stop
                self.filter.stop(every)

    def _start_episodes(self, state: StateIn) -> None:
        previous = self.latest.episode_ids if self.latest is not None else None
        env_ids = episode_starts(state, previous)  # (K,)
        if len(env_ids):
            self.filter.start_episodes(env_ids, state.q[env_ids])
            if self.stopped_by is not None:  # a new episode does not lift a stop
                self.filter.stop(env_ids)

    def _resume(self, why: str) -> None:
        """Follow the policy again, from rest at the latest measured joint positions."""
        log.info(
            "%s at step %d: resuming from the measured joint positions",
            why,
            self.latest.step if self.latest is not None else 0,
        )
        self.stopped_by = None
        if self.filter is not None:
            self.filter.resume(np.arange(self.num_envs), self.latest.q)
        if self.pending is not None:  # its wait starts now
            self.deadline = self.clock() + self.config.watchdog_s

    # --- outputs --------------------------------------------------------------------------

    def _answer(self) -> None:
        """Answer the pending state if its action is here, or brake if stopped."""
        state = self.pending
        if state is None:
            return
        if self.stopped_by is not None:
            if self.clock() >= self.brake_at:
                self._command(self.filter.brake(state.q, state.dq), state)
            return
        if self.action is None or self.action.step != state.step:
            return
        action, self.action = self.action, None
        output = self.filter.command(
            action.action, state.q, state.dq, self.env_transitions, action.stale(state)
        )
        self._command(output, state)
        self.reports.account(output.filtered, state.step)

    def _check_watchdog(self) -> None:
        if self.pending is None or self.stopped_by is not None:
            return
        if self.clock() < self.deadline:
            return
        step = self.pending.step
        if self.policy_heard:
            log.warning(
                "no action for state %d within %.2f s: braking every environment",
                step,
                self.config.watchdog_s,
            )
        else:
            log.info(
                "no action from the policy yet (state %d): holding every environment until "
                "its first action",
                step,
            )
        self.stopped_by = "watchdog"
        self.reports.counts["watchdog"] += 1
        self.filter.stop(np.arange(self.num_envs))
        reason = f"no action within {self.config.watchdog_s} s of state {step}"
        self._notice("WATCHDOG_STOP", step, "watchdog", reason)
        self.brake_at = self.clock()  # this state waited long enough
        self._answer()

    def _command(self, output: SafeOutput, state: StateIn) -> None:
        self.answered = SafeAnswer(output, state.step, state.episode_ids)
        self.emit(self.answered)
        self.pending = None
        self.last_command_at = self.clock()
        self.reports.command(output, self.clock() - self.received_at)

    def _notice(self, kind: str, step: int, stage: str, reason: str) -> None:
        """An event about every environment."""
        self.emit(Notice(kind, step, np.arange(self.num_envs or 0), stage, reason))
