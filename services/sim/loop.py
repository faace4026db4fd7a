"""How the sim paces its steps (`SimLoopConfig`), as two loops over its shell.

Lock-step (default): the sim steps only on the command of the current step, so a slow
policy slows the sim down instead of losing steps; while it waits it publishes the scenes
and the state again every `resend_s`, so services that start after it get going.
Free-running (`--realtime`): one step per policy period of wall-clock time with the latest
command, whatever its step, or holding the current joint positions until one arrives.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated

from hamnet.runtime.errors import ConfigError
from hamnet.runtime.shell_config import Flattened, ReportConfig
from hamnet.sim.env import Command

if TYPE_CHECKING:
    from hamnet.sim.shell import SimShell


@dataclass(frozen=True)
class SimLoopConfig:
    """How the shell paces its steps."""

    realtime: bool = False
    """Free-running: step every policy period of wall-clock time with the latest command,
    instead of waiting for the command of each step (lock-step)."""
    max_steps: int = 0
    """Exit after this many policy steps (0: run until stopped)."""
    resend_s: float = 1.0
    """Lock-step: while waiting for a command, publish the scenes and the state again this
    often, s, so services started after the sim get going."""
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)
    stall_s: float = 2.0
    """Seconds without a command, once the first has come, that make a stall of the closed
    loop (`hamnet.sim.stall`): logged, and counted as a `loop_stalls` event in the health
    reports that `hamnet up` sums. 2 s is 20 periods of the paper's 10 Hz policy."""

    def __post_init__(self) -> None:
        for name in ("resend_s", "stall_s"):
            value = getattr(self, name)
            if value <= 0:
                raise ConfigError(f"--{name.replace('_', '-')} must be > 0 s, got {value}")


def lock_step(shell: SimShell) -> None:
    """Step on the command of the current step only; resend while waiting."""
    last_sent = time.monotonic()
    while not shell.finished:
        shell.turn()
        received = shell.service.receive(timeout=0.05)
        if received is None:
            if time.monotonic() - last_sent >= shell.loop.resend_s:
                shell.publish_all()
                last_sent = time.monotonic()
            continue
        answer = shell.handle(received)
        if answer is None:
            continue
        step, command = answer
        if step != shell.step:
            shell.ignore(step)
            continue
        shell.advance(command)
        shell.commanded()  # the wait for the next command starts once this step is done
        last_sent = time.monotonic()


def free_running(shell: SimShell) -> None:
    """Step once per policy period with the latest command (holding until the first)."""
    period = shell.env.config.policy_period_s
    command: Command | None = None
    tick = time.monotonic()
    while not shell.finished:
        shell.turn()
        tick += period
        while shell.service.running and (remaining := tick - time.monotonic()) > 0:
            received = shell.service.receive(timeout=min(remaining, 0.1))
            answer = shell.handle(received) if received is not None else None
            if answer is not None:
                command = answer[1]  # whatever its step
                shell.commanded()
        if shell.finished:
            break
        if command is None:
            shell.hold()
        else:
            shell.advance(command)
        if time.monotonic() - tick > period:  # fell a period behind: do not burst to catch up
            shell.late += 1
            tick = time.monotonic()
