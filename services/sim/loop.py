"""How the sim paces its steps (`SimLoopConfig`), as two loops over its shell.

Lock-step (default): the sim steps only on the command of the current step, so a slow
policy slows the sim down instead of losing steps; while it waits it publishes the scenes
and the state again every `resend_s`, so services that start after it get going.
Free-running (`--realtime`): one step per policy period of wall-clock time with the latest
command, whatever its step, or holding the current joint positions until one arrives.
Both watch the commands arrive: a stall of the closed loop is logged and counted
(`hamnet.sim.stall`), and so is a command that answers another step than the current one.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated

from hamnet.messages.safe_command import Command
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.shell_config import Flattened, ReportConfig

if TYPE_CHECKING:
    from hamnet.sim.shell import SimShell

log = logging.getLogger(__name__)


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
        _turn(shell)
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
            _ignore(shell, step)
            continue
        shell.advance(command)
        _commanded(shell)  # the wait for the next command starts once this step is done
        last_sent = time.monotonic()


def free_running(shell: SimShell) -> None:
    """Step once per policy period with the latest command (holding until the first)."""
    period = shell.env.config.policy_period_s
    command: Command | None = None
    tick = time.monotonic()
    while not shell.finished:
        _turn(shell)
        tick += period
        while shell.service.running and (remaining := tick - time.monotonic()) > 0:
            received = shell.service.receive(timeout=min(remaining, 0.1))
            answer = shell.handle(received) if received is not None else None
            if answer is not None:
                command = answer[1]  # whatever its step
                _commanded(shell)
        if shell.finished:
            break
        if command is None:
            shell.hold()
        else:
            shell.advance(command)
        if time.monotonic() - tick > period:  # fell a period behind: do not burst to catch up
            shell.late += 1
            tick = time.monotonic()


def _turn(shell: SimShell) -> None:
    """Once per turn of the loop: the rate line and the stall watch, when due."""
    shell.report.tick()
    if shell.stall.check(time.monotonic()):
        log.warning(
            "no command for %.1f s at step %d: the closed loop is stalled",
            shell.loop.stall_s,
            shell.step,
        )
        shell.service.count_event("loop_stalls")


def _commanded(shell: SimShell) -> None:
    """A command was used: a stall, if any, is over."""
    ended = shell.stall.commanded(time.monotonic())
    if ended is not None:
        log.info("commands arrive again at step %d after a %.1f s stall", shell.step, ended)


def _ignore(shell: SimShell, step: int) -> None:
    """Count a command that answered another step than the current one."""
    shell.stale += 1
    if shell.stale == 1:
        log.info(
            "ignoring a command for step %d at step %d (further ones are counted in the rate line)",
            step,
            shell.step,
        )
