"""The safety supervisor on a fake clock, without Zenoh and without sleeping: each state
waits for its own action, the watchdog fires at the deadline of the oldest unanswered state
(not of each copy or successor), braking is paced at the policy period, an action of any
step resumes tracking, the e-stop latch ignores actions until reset, a restarted sim starts
afresh, an implausible step is dropped, and clip, rejection and statistics events follow
the filter's reports."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.fr3.limits import Q_HOME
from hamnet.safety.estop import EStop
from hamnet.safety.filter import SafetyFilter
from hamnet.safety.reports import STATISTICS, Notice
from hamnet.safety.supervisor import (
    BRAKE_PACE,
    ActionIn,
    SafeAnswer,
    SafetyLoopConfig,
    StateIn,
    Supervisor,
)
from tests.clock import Clock

B, J = 2, 7
WATCHDOG_S = 0.3
PERIOD_S = 0.1
"""The default TrajectoryConfig's policy period."""


def supervisor(**config) -> tuple[Supervisor, list, Clock]:
    """A supervisor of B environments, what it emits, and its clock."""
    emitted: list[SafeAnswer | Notice] = []
    clock = Clock(100.0)
    config = SafetyLoopConfig(**{"num_envs": B, "watchdog_s": WATCHDOG_S, **config})
    return Supervisor(emitted.append, config, estop=EStop(), clock=clock), emitted, clock


def state(step: int, run: int = 0, q: np.ndarray | None = None, episode_step: int | None = None):
    """State `step` of `run`: B environments at q (default home), at rest, episodes 0..B-1."""
    q = np.tile(Q_HOME, (B, 1)) if q is None else q  # (B, J)
    episode_step = step if episode_step is None else episode_step
    return StateIn(run, step, q, np.zeros((B, J)), np.arange(B), np.full(B, episode_step))


def action(step: int, value: float = 0.0) -> ActionIn:
    return ActionIn(step, np.full((B, 21), value, np.float32), None)


def commands(emitted: list) -> list[SafeAnswer]:
    return [item for item in emitted if isinstance(item, SafeAnswer)]


def notices(emitted: list, kind: str | None = None) -> list[Notice]:
    return [n for n in emitted if isinstance(n, Notice) and kind in (None, n.kind)]


def braking(command: SafeAnswer) -> bool:
    return command.output.filtered is None and bool(command.output.stopping.all())


def test_config_refuses_a_watchdog_that_never_waits() -> None:
    with pytest.raises(ValueError, match="watchdog_s"):
        SafetyLoopConfig(watchdog_s=0.0)
    with pytest.raises(ValueError, match="num_envs"):
        SafetyLoopConfig(num_envs=-1)


def test_a_state_is_answered_only_with_its_own_action() -> None:
    core, emitted, _ = supervisor()
    core.on_state(state(0))
    core.on_action(action(1))  # computed for another state: not state 0's
    assert emitted == []
    core.on_action(action(0))
    [command] = commands(emitted)
    assert command.step == 0 and command.output.filtered is not None
    assert command.episode_ids.tolist() == [0, 1] and core.pending is None


def test_watchdog_brakes_every_environment_at_the_deadline() -> None:
    """The deadline is `watchdog_s` after the state arrived: one WATCHDOG_STOP event naming
    every environment, then the state's brake at once."""
    core, emitted, clock = supervisor()
    core.on_state(state(0), received=clock.now)
    assert core.due() == pytest.approx(100.0 + WATCHDOG_S)
    clock.now += WATCHDOG_S - 0.01
    core.tick()
    assert emitted == []
    clock.now += 0.01
    core.tick()
    [watchdog] = notices(emitted)
    assert watchdog.kind == "WATCHDOG_STOP" and watchdog.step == 0
    assert watchdog.env_ids.tolist() == [0, 1] and watchdog.stage == "watchdog"
    [command] = commands(emitted)
    assert emitted[-1] is command and command.step == 0 and braking(command)
    assert core.stopped_by == "watchdog"


def test_watchdog_waits_from_the_oldest_unanswered_state() -> None:
    """A free-running executor's next state, and the lock-step sim's copy of the state it
    waits on, do not restart the wait: otherwise states faster than the watchdog would keep
    it from ever firing."""
    core, emitted, clock = supervisor()
    core.on_state(state(0))
    clock.now += 0.2
    core.on_state(state(0))  # the sim sends its state again
    core.on_state(state(1))  # an executor moved on
    assert core.reports.counts["superseded"] == 1
    clock.now += WATCHDOG_S - 0.2
    core.tick()
    assert [n.step for n in notices(emitted, "WATCHDOG_STOP")] == [1]
    assert [c.step for c in commands(emitted)] == [1]


def test_braking_is_paced_at_the_policy_period() -> None:
    """While stopped, a state arriving right after the last brake waits until BRAKE_PACE
    policy periods have passed since it; a state arriving later is braked at once."""
    core, emitted, clock = supervisor()
    core.on_state(state(0))
    clock.now += WATCHDOG_S
    core.tick()
    braked_at = clock.now
    core.on_state(state(1))
    assert len(commands(emitted)) == 1
    assert core.due() == pytest.approx(braked_at + BRAKE_PACE * PERIOD_S)
    clock.now = core.due() - 1e-6
    core.tick()
    assert len(commands(emitted)) == 1
    clock.now = core.due()
    core.tick()
    clock.now += PERIOD_S
    core.on_state(state(2))
    assert [c.step for c in commands(emitted)] == [0, 1, 2]
    assert all(braking(c) for c in commands(emitted))
    assert len(notices(emitted, "WATCHDOG_STOP")) == 1  # one event per stop, not per state


def test_an_action_of_any_step_resumes_tracking() -> None:
    """A late action (for a state already braked) says the policy is alive: the filter
    resumes, and the next state waits for its own action again with a fresh deadline."""
    core, emitted, clock = supervisor()
    core.on_state(state(0))
    clock.now += WATCHDOG_S
    core.tick()
    core.on_state(state(1))  # its brake is not due yet (paced)
    clock.now += PERIOD_S / 2
    core.on_action(action(0))  # late
    assert core.stopped_by is None and core.reports.counts["stale"] == 1
    assert core.due() == pytest.approx(clock.now + WATCHDOG_S)  # state 1 waits afresh
    core.on_action(action(1))
    tracked = commands(emitted)[-1]
    assert tracked.step == 1 and not braking(tracked)
    np.testing.assert_allclose(tracked.output.q_ref[:, -1], np.tile(Q_HOME, (B, 1)), atol=1e-6)


def test_estop_ignores_actions_until_reset() -> None:
    """Latched before the first state: the first state is braked at once, actions are
    ignored, the watchdog stays quiet; after reset the policy is followed again."""
    core, emitted, clock = supervisor()
    core.estop.request("stop")
    core.apply_estop()
    assert [n.kind for n in notices(emitted)] == ["ESTOP_LATCHED"]
    core.on_state(state(0))
    core.on_action(action(0))
    clock.now += 10 * WATCHDOG_S
    core.tick()
    assert [braking(c) for c in commands(emitted)] == [True]
    assert core.reports.counts["ignored"] == 1 and not notices(emitted, "WATCHDOG_STOP")
    core.apply_estop()  # the loop does at every turn: the status its answers report
    assert core.estop.status == {"step": 0, "stopped_by": "estop"}
    core.estop.request("reset")
    core.apply_estop()
    assert notices(emitted)[-1].kind == "ESTOP_RESET" and core.stopped_by is None
    core.on_state(state(1))
    core.on_action(action(1))
    assert [braking(c) for c in commands(emitted)] == [True, False]


def test_an_answered_state_sent_again_gets_the_same_command() -> None:
    core, emitted, _ = supervisor()
    core.on_state(state(0))
    core.on_action(action(0, 0.3))
    core.on_state(state(0))
    first, again = commands(emitted)
    assert again is first


def test_a_restarted_sim_starts_every_episode_afresh() -> None:
    """State 0 of a new run, with the old run's episode ids and steps, gets a fresh filter's
    command (not one smoothed on from the old run), although the old run was at step 3."""
    core, emitted, _ = supervisor()
    for k in range(4):
        core.on_state(state(k, run=1))
        core.on_action(action(k, 0.5))
    q = np.tile(Q_HOME, (B, 1)) + 0.05  # (B, J)
    core.on_state(state(0, run=2, q=q, episode_step=4))
    core.on_action(action(0, 0.5))
    assert [c.step for c in commands(emitted)] == [0, 1, 2, 3, 0]
    assert core.reports.counts["restarts"] == 1
    fresh = SafetyFilter(q).command(np.full((B, 21), 0.5), q, np.zeros((B, J)), 0)
    np.testing.assert_allclose(commands(emitted)[-1].output.q_ref, fresh.q_ref, atol=1e-9)


def test_an_implausible_step_is_dropped() -> None:
    """A forged step far ahead must not become the state that waits (it would supersede the
    real one): it is counted and the real next state is answered."""
    core, emitted, _ = supervisor()
    core.on_state(state(0))
    core.on_action(action(0))
    core.on_state(state(10**12))
    assert core.reports.counts["implausible"] == 1 and core.pending is None
    core.on_state(state(1))
    core.on_action(action(1))
    assert [c.step for c in commands(emitted)] == [0, 1]


def test_a_nan_row_becomes_a_rejection_event_for_that_row() -> None:
    core, emitted, _ = supervisor()
    core.on_state(state(0))
    nan = action(0)
    nan.action[1, 2] = np.nan
    core.on_action(nan)
    [rejection] = notices(emitted, "REJECTED_NONFINITE")
    assert rejection.env_ids.tolist() == [1] and rejection.stage == "nonfinite_guard"
    assert core.reports.counts["rejected"] == 1


def test_clip_events_are_rate_limited_and_statistics_are_periodic() -> None:
    """Saturating actions: the first clip is reported at once, the next ones only after
    `clip_event_period_s`, counting every command since; the statistics event comes every
    `stats_period_s` with every stage's commands (B per command)."""
    core, emitted, clock = supervisor(clip_event_period_s=1.0, stats_period_s=2.0)
    for k in range(4):
        core.on_state(state(k))
        core.on_action(action(k, 5.0))
        core.tick()
    clips = notices(emitted, "CLIPPED_MAGNITUDE")
    assert len(clips) == 1 and clips[0].stats[0].commands == B
    assert not notices(emitted, STATISTICS)
    clock.now += 2.0
    core.on_state(state(4))
    core.on_action(action(4, 5.0))
    core.tick()
    clips = notices(emitted, "CLIPPED_MAGNITUDE")
    assert len(clips) == 2 and clips[1].stats[0].commands == 4 * B  # states 1-4
    [stats] = notices(emitted, STATISTICS)
    guard = {s.stage: s.commands for s in stats.stats}["nonfinite_guard"]
    assert guard == 5 * B
