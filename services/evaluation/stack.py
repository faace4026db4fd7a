"""Evaluating over the service stack: perception, the policy and the safety filter run as
their own `hamnet` processes on Zenoh, as they are deployed, and this process is their sim.

It serves the sim's contract through the sim's own shell (`hamnet.sim.shell.SimShell`,
lock-step: each step waits for its command) on the evaluation's `VectorEnv`, so the planned
episodes, the arm's events and the books (`outcomes.Outcomes`) are those of the in-process
evaluation; what differs is everything between state and command: messages, the services'
own decoding and timing, and the safety service's filter (`--safety-profile`, deploy by
default here as on the robot). A safety stop is what the service says it did: its
`WATCHDOG_STOP` and `ESTOP_LATCHED` events name the environments. The watchdog waits
`WATCHDOG_S`: the sim waits for every command, so lateness is this machine's, not the
policy's; only a dead policy should stop the arm here.
"""

from __future__ import annotations

import contextlib
import logging
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from hamnet.evaluation.outcomes import Labels, Outcomes
from hamnet.evaluation.play import Frame
from hamnet.evaluation.records import EpisodeRecord
from hamnet.messages.safe_command import Command
from hamnet.perception.config import student_clouds
from hamnet.policy.policy import Policy
from hamnet.proto.safety_pb2 import SafetyEvent, SafetyEventKind
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.ports import Ports
from hamnet.runtime.pubsub import Received
from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.runtime.tensor import from_tensor
from hamnet.runtime.transport import TransportConfig
from hamnet.sim.env import StepResult, VectorEnv
from hamnet.sim.loop import SimLoopConfig, lock_step
from hamnet.sim.shell import SimShell

log = logging.getLogger(__name__)

WATCHDOG_S = 30.0
"""The safety service's wait for an action, s (its default 0.3 s is the real robot's)."""

STOPS = (SafetyEventKind.WATCHDOG_STOP, SafetyEventKind.ESTOP_LATCHED)
"""Safety events that stop following the policy."""

EVENTS = Ports(inputs={"safety_event": "safety/<w>/event"}, outputs={})
"""What the evaluation reads beside the sim's inputs."""


def service_commands(
    weights: str, policy: Policy, safety_profile: str, transport: TransportConfig
) -> list[list[str]]:
    """The `hamnet` command lines of perception, policy and safety for `policy` (the
    checkpoint or shipped name `weights`): a student's perception sees clouds as the
    cameras do, as it is deployed."""
    net = ["--namespace", transport.namespace, "--rendezvous", transport.rendezvous]
    seen = student_clouds()  # as the trainer's DAgger and the in-process evaluation see them
    flags = {"visibility": seen.visibility, "noise-std": seen.noise_std, "dropout": seen.dropout}
    clouds = [] if policy.config.privileged else [f"--clouds.{k}={v}" for k, v in flags.items()]
    perception = ["perception", *clouds, *net] if policy.config.clouds else []
    return [
        command
        for command in (
            perception,
            ["policy", "--checkpoint", weights, "--deterministic", *net],
            ["safety", "--profile", safety_profile, "--watchdog-s", str(WATCHDOG_S), *net],
        )
        if command
    ]


@contextlib.contextmanager
def services(commands: list[list[str]], logs: Path) -> Iterator[list[subprocess.Popen]]:
    """The processes of `commands` (`python -m hamnet ...`), each logging to a file in
    `logs`; stopped (SIGTERM, then SIGKILL) when the block ends."""
    logs.mkdir(parents=True, exist_ok=True)
    processes = []
    try:
        for command in commands:
            out = (logs / f"{command[0]}.log").open("w")
            processes.append(
                subprocess.Popen(
                    [sys.executable, "-m", "hamnet", *command],
                    stdout=out,
                    stderr=subprocess.STDOUT,
                    env={**os.environ, "PYTHONUNBUFFERED": "1"},
                )
            )
        yield processes
    finally:
        for process in processes:
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()


class EvalShell(SimShell):
    """The sim's shell over a batch of started episodes: it steps until every counted one
    has ended, keeping their books."""

    def __init__(self, service: Service, env: VectorEnv) -> None:
        super().__init__(service, env, SimLoopConfig())
        key = service.ports(EVENTS)["safety_event"]
        service.inbox.subscribe("safety_event", key, decoder=payload_decoder(SafetyEvent))
        self.outcomes: Outcomes | None = None
        self.frame: Frame | None = None
        """Sees every step's observation before it is stepped (a recording)."""
        self.steps = 0
        """Steps of the batch under way."""

    def play(self, started, labels: Labels) -> list[EpisodeRecord]:
        """Serve the episodes just started (`started`, their first observation)."""
        self.step += 1  # a new step number: the services answer it afresh
        self.observation, self.steps = started, 0
        self.outcomes = Outcomes(self.env, started, labels)
        self.publish_all()
        lock_step(self)
        if not self.service.running:
            raise InterruptedError("stopped before the batch ended")
        return self.outcomes.done()

    @property
    def finished(self) -> bool:
        return not self.service.running or not self.outcomes.live.any()

    def handle(self, received: Received) -> tuple[int, Command] | None:
        if received.name == "safety_event":
            if received.value.kind in STOPS:
                stopped = from_tensor(received.value.env_ids, np.int32, (None,))
                self.outcomes.stopped(stopped.astype(np.int64))
            return None
        return super().handle(received)

    def advance(self, command: Command) -> StepResult:
        if self.frame is not None:
            self.frame(self.steps, self.observation)
        result = super().advance(command)
        self.outcomes.step(result, command.tau_limit)
        self.steps += 1
        return result


def stack_identity() -> ServiceIdentity:
    """This process on the network: the sim's worker 0."""
    return ServiceIdentity("sim", "0")
