"""The failure reasons the sim's termination does not name, read from real MuJoCo: an arm
link touching a scene cuboid, a joint at its torque clip, a safety stop; and the books that
turn them into one reason per episode."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hamnet.evaluation.arm_events import ArmEvents
from hamnet.evaluation.outcomes import Labels, Outcomes
from hamnet.messages.safe_command import hold_command
from hamnet.sim.env import VectorEnv
from hamnet.sim.stages import stage_config

B = 2


def make_env(timeout: int = 100) -> VectorEnv:
    """B easy-stage environments whose episodes time out after `timeout` steps."""
    config = stage_config("easy", num_envs=B, num_objects=2, nthread=1)
    task = dataclasses.replace(config.task, timeout=timeout)
    env = VectorEnv(dataclasses.replace(config, task=task))
    env.reset(seed=0)
    return env


def hold(env: VectorEnv, tau_max: float | None = None):
    """One step holding the arm where it is (torque clip `tau_max` on every joint if set)."""
    command = hold_command(env.observe().q, env.config.control_samples)
    if tau_max is not None:
        command = dataclasses.replace(command, tau_limit=np.full_like(command.tau_limit, tau_max))
    return env.step(command)


LINKS_IN_TABLE = np.array([0.0, 1.5, 0.0, -0.6, 0.0, 2.0, 0.78])
"""Reaching down through the easy stage's table: forearm, wrist and flange inside it."""
PADDLE_IN_TABLE = np.array([0.0, 0.9, 0.0, -1.2, 0.0, 2.1, 0.78])
"""Reaching down less: only the paddle inside the table."""


def test_an_arm_link_in_the_table_is_a_collision_and_the_paddle_is_not() -> None:
    """At their starts no arm touches the scene; then environment 0's links are put into
    the table and environment 1's paddle alone: only the first is a collision."""
    env = make_env()
    events = ArmEvents(env)
    assert not events.collided(np.arange(B)).any()
    q = np.stack([LINKS_IN_TABLE, PADDLE_IN_TABLE])
    away = np.tile([0.0, 2.0, 2.0], (B, 1))  # the object out of the way
    env.physics.set_state(np.arange(B), q, away, np.tile([1.0, 0.0, 0.0, 0.0], (B, 1)))
    assert events.collided(np.arange(B)).tolist() == [True, False]


def test_a_joint_at_its_clip_is_at_the_torque_limit() -> None:
    """Tracking a reference 0.3 rad away with a 1e-3 N m clip saturates every joint;
    holding still within the FR3's own limits saturates none."""
    env = make_env()
    events = ArmEvents(env)
    command = hold_command(env.observe().q + 0.3, env.config.control_samples)  # far off
    env.step(dataclasses.replace(command, tau_limit=np.full_like(command.tau_limit, 1e-3)))
    assert events.torque_limited(np.full((B, 7), 1e-3)).all()
    hold(env)
    assert not events.torque_limited(hold_command(env.observe().q, 8).tau_limit).any()


def test_the_books_name_one_reason_per_episode() -> None:
    """A stop in environment 0 makes its timeout a safety stop; environment 1 times out."""
    env = make_env(timeout=2)
    started = env.observe()
    outcomes = Outcomes(env, started, Labels(["flat", "flat"], ["a", "b"], [0, 0], [0, 1]))
    outcomes.stopped(np.array([0]))
    while outcomes.live.any():
        result = hold(env)
        outcomes.step(result, np.full((B, 7), 1e9))
    records = outcomes.done()
    assert [r.reason for r in records] == ["safety_stop", "timeout"]
    assert [r.length for r in records] == [2, 2]
    assert records[0].start_distance == pytest.approx(
        float(np.linalg.norm(started.object_pose[0, :3] - started.goal_pose[0, :3]))
    )
