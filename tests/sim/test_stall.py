"""Stalls of the closed loop as the sim sees them (`hamnet.sim.stall`), and the sim shell
reporting one as an event when commands stop coming."""

from __future__ import annotations

import logging
import time

import numpy as np
import pytest

from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.messages.safe_command import hold_command
from hamnet.runtime.codec import encode
from hamnet.runtime.shell_config import ReportConfig
from hamnet.runtime.tensor import from_tensor
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.shell import SimLoopConfig, SimShell
from hamnet.sim.stall import StallWatch
from tests.scripted import ScriptedService
from tests.sim.test_shell import safe_command

STALL_S = 0.3


def test_a_wait_past_the_limit_is_one_stall_until_a_command_ends_it() -> None:
    watch = StallWatch(limit_s=2.0)
    assert not watch.check(100.0)  # before the first command: start-up, not a stall
    assert watch.commanded(100.0) is None
    assert not watch.check(101.9)
    assert watch.check(102.5) and not watch.check(110.0)  # one stall, however long
    assert watch.stalls == 1
    assert watch.commanded(112.0) == pytest.approx(12.0)
    assert not watch.check(113.0) and watch.check(114.5) and watch.stalls == 2


def test_the_limit_must_be_positive() -> None:
    with pytest.raises(ValueError, match="limit_s"):
        StallWatch(limit_s=0.0)


def test_the_sim_counts_a_stall_when_commands_stop_and_logs_its_end(caplog) -> None:
    """Commands 0 and 1 come at once, command 2 only after more than `stall_s`: one
    `loop_stalls` event (what the health reports carry), and the log says when it ended."""
    caplog.set_level(logging.INFO, logger="hamnet.sim")
    env = VectorEnv(SimConfig(num_envs=2, num_objects=2, nthread=1))
    state_seen: dict[int, float] = {}

    def script(published):
        state = [m for topic, m in published if topic == "state"][-1]
        step = state.header.step
        if step >= 3:
            return "end"
        state_seen.setdefault(step, time.monotonic())
        if step == 2 and time.monotonic() - state_seen[2] < 3 * STALL_S:
            return None  # the loop is stalled: nothing arrives
        command = hold_command(from_tensor(state.q, np.float32, (2, J)), env.config.control_samples)
        return "command", encode(safe_command(command, step))

    service = ScriptedService(script, idle=True)
    loop = SimLoopConfig(report=ReportConfig(report_period_s=1e9), stall_s=STALL_S)
    shell = SimShell(service, env, loop)
    assert shell.run() == 0
    assert service.events == {"loop_stalls": 1} and shell.step == 3
    assert any("after a" in r.message and "stall" in r.message for r in caplog.records)
