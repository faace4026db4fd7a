"""The monitor's Zenoh shell: subscribes to the whole stack of one worker and hands each
decoded frame to the view.

Consumes `sim/<w>/state`, `sim/<w>/scene`, `sim/<w>/transition`, `perception/<w>/tokens`,
`policy/<w>/action`, `safety/<w>/event` and `trainer/metrics`; publishes nothing but its
Health. It never slows the stack: it runs in its own process, its inbox is bounded (the
oldest payload is dropped, reason `overflow`), and the pacer decides from a message's
header alone, before any tensor is decoded, whether its step is drawn; the state, clouds
and action of a skipped step are dropped with reason `rate`. Transitions are always
decoded (the success rate counts every episode); their reward terms are drawn only on
drawn steps. Both kinds of drop are counted in Health.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from google.protobuf.message import Message

from hamnet.monitor.config import MonitorLoopConfig
from hamnet.monitor.decode import (
    decode_action,
    decode_event,
    decode_metrics,
    decode_scene,
    decode_state,
    decode_tokens,
    decode_transition,
)
from hamnet.monitor.pacing import FramePacer
from hamnet.monitor.view import MonitorView
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafetyEvent
from hamnet.proto.sim_pb2 import RobotState, Scene, Transition
from hamnet.proto.trainer_pb2 import Metrics
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service
from hamnet.runtime.tensor import PayloadError

log = logging.getLogger(__name__)

PORTS = Ports(
    inputs={
        "state": "sim/<w>/state",
        "scene": "sim/<w>/scene",
        "transition": "sim/<w>/transition",
        "tokens": "perception/<w>/tokens",
        "action": "policy/<w>/action",
        "event": "safety/<w>/event",
        "metrics": "trainer/metrics",
    },
    outputs={},
)
"""What the monitor reads and writes (`hamnet.runtime.ports`)."""


class MonitorShell:
    """One monitor on the network: subscriptions, pacing and the loop."""

    def __init__(
        self, service: Service, view: MonitorView, loop: MonitorLoopConfig | None = None
    ) -> None:
        self.service, self.view = service, view
        self.loop = loop if loop is not None else MonitorLoopConfig()
        self.env = view.config.env
        self.pacer = FramePacer(view.config.min_frame_interval_s)
        port = service.ports(PORTS)
        env = self.env
        self.scene_key = port["scene"]
        reads: dict[str, tuple[type[Message], Callable[[Any], Any]]] = {
            "state": (RobotState, self._paced(decode_state)),
            "tokens": (PerceptionTokens, self._paced(decode_tokens)),
            "action": (PolicyAction, self._paced(decode_action)),
            "transition": (Transition, self._transition),
            "scene": (Scene, lambda message: decode_scene(message, env)),
            "event": (SafetyEvent, decode_event),
            "metrics": (Metrics, decode_metrics),
        }
        for name, read in reads.items():
            service.inbox.subscribe(name, port[name], decoder=payload_decoder(*read))
        self.handlers: dict[str, Callable[[Any], None]] = {
            "state": view.on_state,
            "tokens": view.on_clouds,
            "action": view.on_action,
            "transition": view.on_transition,
            "scene": view.on_scene,
            "event": view.on_event,
            "metrics": view.on_metrics,
        }
        self.report = LoopReport(self.loop.report.report_period_s, self._line, logger=log)
        self.scene_seen = False
        """Whether the focus environment's scene has arrived (else the sim is asked for it)."""

    def run(self) -> int:
        """Draw what arrives until stopped; returns the exit status."""
        log.info(
            "watching worker %s, environment %d, at most %.0f steps/s",
            self.service.identity.worker,
            self.env,
            self.view.config.max_rate_hz,
        )
        while self.service.running:
            received = self.service.receive(timeout=0.1)
            if received is not None and received.value is not None:  # None: not the focus env
                self.handlers[received.name](received.value)
                self.scene_seen |= received.name == "scene"
                if received.name == "state" and not self.scene_seen:
                    self.service.inbox.catch_up("scene", self.scene_key)  # started late
            self.report.total(drawn=self.pacer.drawn)
            self.report.tick()
        return 0

    def _paced(self, decode: Callable[[Any, int], Any]) -> Callable[[Message], Any]:
        """`decode` of the focus environment, for the messages of a step the pacer draws:
        the message of a skipped step is dropped before any tensor is decoded."""

        def read(message: Message) -> Any:
            step = message.header.step
            if not self.pacer.draw(step, time.monotonic()):
                raise PayloadError(
                    "rate",
                    f"step {step} not drawn: at most "
                    f"{self.view.config.max_rate_hz:g} steps/s (--max-rate-hz)",
                )
            return decode(message, self.env)

        return read

    def _transition(self, message: Transition) -> Any:
        drawn = self.pacer.draw(message.header.step, time.monotonic())
        return decode_transition(message, self.env, drawn)

    def _line(self, w: Window) -> str:
        success = self.view.success
        return (
            f"{w.rate('drawn'):.1f} steps/s drawn, {self.pacer.skipped} skipped in all, "
            f"step {self.view.step}, {success.finished} episodes finished, success rate "
            f"{success.rate:.2f}, {self.service.drops.total} payloads dropped in all"
        )
