"""Random policy actions through the deploy safety filter at 1 kHz references, executed by
a bridge core: what a policy with random weights asks of the robot."""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hamnet.bridge.core import BridgeCommand, BridgeCore
from hamnet.bridge.driver import RobotError
from hamnet.messages.safe_command import hold_command
from hamnet.safety.filter import SafetyFilter
from hamnet.safety.references import TrajectoryConfig


def drive(
    core: BridgeCore, steps: int, seed: int = 0, first: int = 0, paced: bool = False
) -> list[RobotError]:
    """`steps` commands from step `first`; `paced`: one per policy period of the robot's
    clock (a real-time robot), else as fast as they are made (the fake's virtual time)."""
    period = core.samples * core.driver.control_period_s
    trajectory = TrajectoryConfig(
        control_rate_hz=1.0 / core.driver.control_period_s, policy_period_s=period
    )
    rng = np.random.default_rng(seed)
    reading = core.read()
    safety = SafetyFilter(reading.q[None], trajectory=trajectory)
    errors = []
    clock = core.driver.clock
    tick = clock()
    for step in range(first, first + steps):
        reading = core.read()
        action = np.clip(0.7 * rng.standard_normal((1, 21)), -1, 1)
        out = safety.command(action, reading.q[None], reading.dq[None], 0)
        command = dataclasses.replace(hold_command(reading.q[None], core.samples), q_ref=out.q_ref,
                                      kp=out.kp, kd=out.kd, tau_limit=out.tau_limit)  # fmt: skip
        errors += core.execute(BridgeCommand(step, core.episode_id, command), step)
        if paced:
            tick += period
            while clock() < tick:
                time.sleep(core.driver.control_period_s)
            errors += core.poll()
    return errors
