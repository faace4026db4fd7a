"""The sim's Zenoh shell: steps a `VectorEnv` with the safety filter's commands and
publishes what happened.

Consumes `safety/<w>/command` (SafeCommand) and `trainer/schedule` (Schedule: the counter
`env_transitions`, from which the curriculum's `p_near_init` and `p_tight` follow);
produces `sim/<w>/state` (RobotState, every step), `sim/<w>/transition` (Transition, every
step) and `sim/<w>/scene` (Scene, for the environments that start a new episode). A Zenoh
query on `sim/<w>/scene` is answered with the scenes of every environment, so services
started late catch up (`Inbox.catch_up`).

Steps are numbered: state k (`header.step` = k) is the state after k policy steps; the
command answering it carries `header.step` = k; transition k is its outcome, published just
before state k+1 (and the scenes of the episodes that start in it, before that state).
The loops that pace the steps (lock-step or free-running) are in `hamnet.sim.loop`.
"""

from __future__ import annotations

import functools
import logging
import time

import numpy as np

from hamnet.messages.robot_state import Observation
from hamnet.messages.robot_state import encode_observation as encode_state
from hamnet.messages.safe_command import Command, hold_command
from hamnet.messages.safe_command import decode as decode_command
from hamnet.messages.scene import encode as encode_scene
from hamnet.messages.schedule import decode as decode_schedule
from hamnet.messages.transition import encode as encode_transition
from hamnet.proto.safety_pb2 import SafeCommand
from hamnet.proto.sim_pb2 import Scene
from hamnet.proto.trainer_pb2 import Schedule
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.events import EPISODES_ENDED, EPISODES_SUCCEEDED
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.ports import Ports
from hamnet.runtime.pubsub import Received
from hamnet.runtime.service import Service
from hamnet.sim.curriculum import curriculum_values
from hamnet.sim.env import StepResult, VectorEnv
from hamnet.sim.loop import SimLoopConfig, free_running, lock_step
from hamnet.sim.stall import StallWatch

log = logging.getLogger(__name__)

PORTS = Ports(
    inputs={"command": "safety/<w>/command", "schedule": "trainer/schedule"},
    outputs={
        "state": "sim/<w>/state",
        "scene": "sim/<w>/scene",
        "transition": "sim/<w>/transition",
    },
)
"""What the sim reads and writes (`hamnet.runtime.ports`)."""


# --- the loop ----------------------------------------------------------------------------


class SimShell:
    """One sim worker on the network: its topics, its step counter and its rates."""

    def __init__(self, service: Service, env: VectorEnv, loop: SimLoopConfig) -> None:
        self.service, self.env, self.loop = service, env, loop
        port = service.ports(PORTS)
        config = env.config
        control_dt = config.policy_period_s / config.control_samples
        command = functools.partial(
            decode_command,
            num_envs=env.num_envs,
            control_samples=config.control_samples,
            control_dt=control_dt,
        )
        inbox = service.inbox
        inbox.subscribe("command", port["command"], decoder=payload_decoder(SafeCommand, command))
        inbox.subscribe(
            "schedule", port["schedule"], decoder=payload_decoder(Schedule, decode_schedule)
        )
        self.state = service.publisher(port["state"])
        self.scene = service.publisher(port["scene"])
        service.inbox.serve("scene_query", port["scene"])
        self.transition = service.publisher(port["transition"])
        self.step = 0
        self.observation: Observation | None = None
        self.stale = 0
        """Commands ignored because they answered another step than the current one."""
        self.stall = StallWatch(loop.stall_s)
        self.late = 0
        """Free-running ticks that started more than a period late."""
        self.report = LoopReport(loop.report.report_period_s, self._line, logger=log)

    def run(self) -> int:
        """Reset, then step until stopped or `max_steps`; returns the exit status."""
        self.observation = self.env.reset()
        self.report.restart()  # rates of the steps, not of the first reset
        self.publish_all()
        mode = "free-running" if self.loop.realtime else "lock-step"
        log.info(
            "%d environments, %s, %.0f ms policy period",
            self.env.num_envs,
            mode,
            1e3 * self.env.config.policy_period_s,
        )
        (free_running if self.loop.realtime else lock_step)(self)
        env_steps = self.step * self.env.num_envs
        log.info("stopped after %d steps (%d environment steps)", self.step, env_steps)
        return 0

    @property
    def finished(self) -> bool:
        """Stopped, or `max_steps` done."""
        return not self.service.running or 0 < self.loop.max_steps <= self.step

    def handle(self, received: Received) -> tuple[int, Command] | None:
        """A command to consider, or None after applying a schedule or answering a query."""
        if received.name == "schedule":
            self.env.set_schedule(curriculum_values(received.value, self.env.config.curriculum))
            log.debug("curriculum: %s", self.env.schedule)
            return None
        if received.name == "scene_query":
            self.scene.answer(received.value, self._scene_of(np.arange(self.env.num_envs)))
            return None
        return received.value

    def hold(self) -> None:
        """Step holding the joint positions (free-running, before the first command)."""
        if self.step == 0:
            log.info("no command yet: holding the joint positions until one arrives")
        self.advance(hold_command(self.observation.q, self.env.config.control_samples))

    def advance(self, command: Command) -> StepResult:
        """Step every environment; publish transition k, new scenes and state k+1; returns
        the step's result."""
        started, resetting = time.perf_counter(), self.env.reset_seconds
        result = self.env.step(command)
        self.report.tick(
            steps=1,
            step_s=time.perf_counter() - started,
            resets=len(result.reset_ids),
            reset_s=self.env.reset_seconds - resetting,
        )
        self.transition.put(encode_transition(result, self.env.reward_names, self.step))
        self.count_episodes(result)
        self.step += 1
        self.observation = result.observation
        if len(result.reset_ids):
            self._publish_scene(result.reset_ids)
        self.state.put(encode_state(self.observation, self.step))
        return result

    def count_episodes(self, result: StepResult) -> None:
        """Count the episodes that ended and those that succeeded (`episodes_ended`,
        `episodes_succeeded`): `hamnet up`'s summary prints their success rate."""
        ended = int((result.terminated | result.truncated).sum())
        if ended:
            self.service.count_event(EPISODES_ENDED, ended)
            self.service.count_event(EPISODES_SUCCEEDED, int(result.success.sum()))

    def publish_all(self) -> None:
        """Scenes of every environment, then the current state."""
        self._publish_scene(np.arange(self.env.num_envs))
        self.state.put(encode_state(self.observation, self.step))

    def _publish_scene(self, env_ids: np.ndarray) -> None:
        self.scene.put(self._scene_of(env_ids))

    def _scene_of(self, env_ids: np.ndarray) -> Scene:
        """The Scene message of the current episodes of `env_ids` (K,)."""
        return encode_scene(self.env.scenes(env_ids), self.step)

    def _line(self, w: Window) -> str:
        """The rate line: steps, resets and the shares of the time inside `VectorEnv.step`
        (resets included) and inside its resets."""
        b = self.env.num_envs
        schedule = ", ".join(f"{k} {v:.2f}" for k, v in self.env.schedule.as_dict().items())
        return (
            f"{w.rate('steps') * b:.0f} env steps/s ({w.rate('steps'):.1f} steps/s of {b} "
            f"envs), {w.rate('resets'):.1f} resets/s, stepping {100 * w.rate('step_s'):.0f}% "
            f"of the time (resets {100 * w.rate('reset_s'):.0f}%), stale commands "
            f"{self.stale}, late ticks {self.late}; {schedule}"
        )
