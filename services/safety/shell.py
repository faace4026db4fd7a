"""The safety service's Zenoh shell: answers every robot state with a safe command, built
from the policy's action for that state, or a smooth stop when there is none.

Consumes `sim/<w>/state` (RobotState k), `policy/<w>/action` (PolicyAction k: the action
for state k; non-finite values pass the transport so that the core rejects them) and
`trainer/schedule` (Schedule: its `env_transitions` drives the xi and eps_x annealing).
Produces `safety/<w>/command` (SafeCommand k, `header.step` = k, as the sim's lock-step
requires) and `safety/<w>/event` (SafetyEvent: rejections, rate-limited clip events,
watchdog and e-stop events, and per-stage statistics every `stats_period_s` with kind
SAFETY_EVENT_KIND_UNSPECIFIED). Serves the queryable `safety/<w>/estop`: `stop` latches a
stop, `reset` releases it, `status` reports; each answer is a JSON object.
One mode per message: STOP when every environment is stopping, else TRACK.

Which state waits for which action, the watchdog, braking pace, the e-stop's effect and a
restarted sim are the supervisor's (`hamnet.safety.supervisor`); this shell only decodes,
hands over and publishes, on the wall clock.
"""

from __future__ import annotations

import logging

from hamnet.messages.schedule import decode as decode_schedule
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.sim_pb2 import RobotState
from hamnet.proto.trainer_pb2 import Schedule
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service
from hamnet.safety.config import SafetyConfig
from hamnet.safety.estop import EStop, on_query
from hamnet.safety.messages import (
    decode_action,
    decode_state,
    encode_command,
    encode_notice,
)
from hamnet.safety.references import TrajectoryConfig
from hamnet.safety.reports import Notice
from hamnet.safety.supervisor import SafeAnswer, SafetyLoopConfig, Supervisor

log = logging.getLogger(__name__)

PORTS = Ports(
    inputs={
        "state": "sim/<w>/state",
        "action": "policy/<w>/action",
        "schedule": "trainer/schedule",
        "estop": "safety/<w>/estop",
    },
    outputs={"command": "safety/<w>/command", "event": "safety/<w>/event"},
)
"""What the safety filter reads and writes (`hamnet.runtime.ports`)."""


class SafetyShell:
    """One safety worker on the network: the supervisor between its topics and the e-stop."""

    def __init__(
        self,
        service: Service,
        config: SafetyLoopConfig | None = None,
        safety: SafetyConfig | None = None,
        trajectory: TrajectoryConfig | None = None,
    ) -> None:
        self.service = service
        self.estop = EStop()
        self.core = Supervisor(self._put, config, safety, trajectory, self.estop)
        port = service.ports(PORTS)
        inbox = service.inbox
        state = payload_decoder(RobotState, lambda m: decode_state(m, self.core.num_envs))
        inbox.subscribe("state", port["state"], decoder=state)
        space = self.core.safety.action_magnitude.space
        actions = payload_decoder(PolicyAction, lambda m: decode_action(m, space))
        inbox.subscribe("action", port["action"], decoder=actions)
        inbox.subscribe(
            "schedule", port["schedule"], decoder=payload_decoder(Schedule, decode_schedule)
        )
        self.command = service.publisher(port["command"])
        self.event = service.publisher(port["event"])
        self.estop_key = port["estop"]

    @property
    def env_transitions(self) -> int:
        """The trainer's newest env_transitions, which the annealing follows."""
        return self.core.env_transitions

    @property
    def control_dt(self) -> float:
        """Duration of one reference sample, s."""
        return self.core.trajectory.control_period_s

    def run(self) -> int:
        """Answer states until stopped; returns the exit status."""
        core = self.core
        queryable = self.service.session.declare_queryable(
            self.estop_key, lambda query: on_query(self.estop, query)
        )
        log.info(
            "watchdog %.2f s, %d samples of %.4f s per policy period, e-stop on %s",
            core.config.watchdog_s,
            core.trajectory.samples_per_period,
            self.control_dt,
            self.estop_key,
        )
        try:
            while self.service.running:
                core.apply_estop()
                due = core.due()
                timeout = 0.05 if due is None else min(0.05, max(due - core.clock(), 0.0))
                received = self.service.receive(timeout=timeout)
                if received is not None:
                    self._handle(received.name, received.value, received.received_ns)
                core.tick()
        finally:
            queryable.undeclare()
        return 0

    def _handle(self, name: str, value, received_ns: int) -> None:
        if name == "schedule":
            self.core.env_transitions = value
        elif name == "action":
            self.core.on_action(value)
        else:  # received_ns is time.monotonic_ns(), the supervisor's clock; 0 when unknown
            self.core.on_state(value, received_ns / 1e9 if received_ns else None)

    def _put(self, item: SafeAnswer | Notice) -> None:
        if isinstance(item, SafeAnswer):
            message = encode_command(item.output, item.step, item.episode_ids, self.control_dt)
            self.command.put(message)
        else:
            self.event.put(encode_notice(item))
