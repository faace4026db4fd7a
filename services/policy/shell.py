"""The policy service's Zenoh shell: one batch of actions for every paired state and tokens.

Consumes `sim/<w>/state` (RobotState k), `perception/<w>/tokens` (PerceptionTokens k),
`sim/<w>/scene` (EnvCode of reset environments, for the EnvCode oracle), `trainer/weights`
(WeightsAnnouncement) and `trainer/schedule` (Schedule); produces `policy/<w>/action`
(PolicyAction k: `header.step` = k, `header.policy_version` = the weights' version, raw
action, log-prob, values, module weights). State and tokens are paired by step (`Pairing`);
a state sent again after its answer gets the same answer again. Steps older than the last
answered are dropped, unless the state comes from another run of the sim (`Header.run`): the
policy follows a restarted sim at once, with fresh episode carries (`hamnet.runtime.freshness`;
a step implausibly far ahead is refused). Without Zenoh: decode and encode
(`hamnet.policy.messages`: a student reads the pose estimator's object pose, only a teacher
the privileged block), the step (`hamnet.policy.serving`), hot reload (`hamnet.policy.reload`).

Rollouts from the service chain (`--rollout-horizon T`, off by default): the shell also
consumes `sim/<w>/transition` (Transition k) and publishes `trainer/<w>/rollout` (RolloutChunks
of T steps) from what it served once the trainer is heard (`hamnet.policy.rollouts`).
"""

from __future__ import annotations

import logging
import time
from typing import Any

from hamnet.messages.action import encode as encode_action
from hamnet.policy import messages as m
from hamnet.policy.observation import PoseNoiseConfig
from hamnet.policy.pairing import Pairing
from hamnet.policy.policy import Policy
from hamnet.policy.reload import HotReload
from hamnet.policy.rollouts import RolloutFeed
from hamnet.policy.serving import PolicyLoopConfig, Serving
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.runtime.compute import torch_device
from hamnet.runtime.freshness import Answered, Verdict
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service

log = logging.getLogger(__name__)

PORTS = Ports(
    inputs={
        "state": "sim/<w>/state",
        "tokens": "perception/<w>/tokens",
        "scene": "sim/<w>/scene",
        "weights": "trainer/weights",
        "schedule": "trainer/schedule",
        "transition": "sim/<w>/transition",
    },
    outputs={"action": "policy/<w>/action", "rollout": "trainer/<w>/rollout"},
)
"""What the policy reads and writes (`hamnet.runtime.ports`)."""


class PolicyShell:
    """One policy worker on the network: pairing, batched inference, hot reload."""

    def __init__(
        self, service: Service, policy: Policy, version: int, config: PolicyLoopConfig | None = None
    ) -> None:
        self.service = service
        self.config = config if config is not None else PolicyLoopConfig()
        compute = self.config.compute
        self.device = torch_device(compute.device, compute.threads)
        self.weights = HotReload(policy, version, self.device)
        model = policy.config
        self.port = port = service.ports(PORTS)
        for name, decoder in m.decoders(model, self.config.rollout_horizon > 0).items():
            service.inbox.subscribe(name, port[name], decoder=decoder)
        self.action = service.publisher(port["action"])
        self.rollouts: RolloutFeed | None = None
        """Rollout chunks of what was served (None: `rollout_horizon` 0)."""
        if self.config.rollout_horizon:
            rollout = service.publisher(port["rollout"])
            self.rollouts = RolloutFeed(
                self.config.rollout_horizon, rollout.put, lambda: rollout.matching
            )
        self.pairing: Pairing[m.StateIn, m.TokensIn] = Pairing(self.config.pending)
        pose_noise = PoseNoiseConfig() if self.config.student_pose_noise else None
        self.serving = Serving(model.env_code_dim, self.device, compute.seed, pose_noise)
        self.answered: Answered[PolicyAction] = Answered()
        """The sim's run followed, the last step answered in it and its action, sent again
        when the sim repeats that state."""
        self.report = LoopReport(self.config.report.report_period_s, self._line, logger=log)
        self.counts = self.report.counts
        """What happened since the last rate line."""

    @property
    def policy(self) -> Policy:
        """The network serving now."""
        return self.weights.policy

    @property
    def version(self) -> int:
        """The version of the weights serving now."""
        return self.weights.version

    @property
    def env_transitions(self) -> int | None:
        """The trainer's counter, None before its first Schedule."""
        return self.weights.env_transitions

    def run(self) -> int:
        """Serve until stopped; returns the exit status."""
        log.info(
            "serving %s version %d on %s (%s)",
            self.policy.architecture,
            self.version,
            self.device,
            "deterministic" if self.config.deterministic else "sampling",
        )
        while self.service.running:
            received = self.service.receive(timeout=0.1)
            if received is not None:
                self._handle(received.name, received.value)
            if self.rollouts is not None and not self.rollouts.trainer_heard:
                # A trainer announces each version once: ask one that started first (once a second).
                self.service.inbox.catch_up("weights", self.port["weights"])
            self.report.tick()
        return 0

    def _handle(self, name: str, value: Any) -> None:
        if self.rollouts is not None and name in ("weights", "schedule"):
            self.rollouts.trainer_heard = True
        if name == "weights":
            self.counts["rejected"] += not self.weights.announce(value)
        elif name == "schedule":
            self.weights.schedule(value)
        elif name == "scene":
            self.serving.scene(*value)
        elif name == "state":
            self._on_state(value)
        elif name == "transition":
            self.rollouts.transition(value)
        elif self._acts_on(self.answered.watermark.judge_step(value.step)):
            self._serve(self.pairing.add_tokens(value.step, value))

    def _acts_on(self, verdict: Verdict) -> bool:
        """Whether a fresh step; stale and implausible ones are counted (a repeat of the
        answered step is not: perception repeats its tokens when the sim repeats a state)."""
        if verdict in (Verdict.STALE, Verdict.IMPLAUSIBLE):
            self.counts[verdict.value] += 1
        return verdict is Verdict.FRESH

    def _on_state(self, state: m.StateIn) -> None:
        verdict = self.answered.follow(state.run, state.step)
        if verdict is Verdict.RESTART:
            self._restart(state)
        elif verdict is Verdict.REPEAT:
            self.action.put(self.answered.message)  # the sim sent it again: the same answer
            self.counts["resent"] += 1
            return
        elif not self._acts_on(verdict):
            return
        self._serve(self.pairing.add_state(state.step, state))

    def _restart(self, state: m.StateIn) -> None:
        """The sim restarted (the first state is no restart: tokens that came before it are
        its run's): drop what belongs to the sim's previous run."""
        log.warning("the sim restarted (another run): following it from step %d", state.step)
        self.counts["restarts"] += 1
        self.pairing.clear("restart")
        self.serving.restart()
        if self.rollouts is not None:
            self.rollouts.restart()

    def _serve(self, pair: tuple[m.StateIn, m.TokensIn] | None) -> None:
        if pair is None:
            return
        state, tokens = pair
        started = time.monotonic()
        acted = self.serving.act(self.policy, state, tokens, self.config.deterministic)
        if acted is None:
            self.counts["mismatch"] += 1
            return
        inputs, action = acted
        message = encode_action(
            state.step,
            self.version,
            state.episode_ids,
            action,
            self.config.deterministic,
            self.policy.config.action_space,
        )
        self.action.put(message)
        self.answered.answer(state.step, message)
        self.counts["actions"] += 1
        self.report.sample("inference_s", time.monotonic() - started)
        if self.rollouts is not None:
            self.rollouts.served(state.step, state.episode_ids, inputs, action, self.version)

    def _line(self, w: Window) -> str:
        drops = self.pairing.dropped
        line = (
            f"{w.rate('actions'):.1f} actions/s, inference median "
            f"{w.median_ms('inference_s'):.1f} ms, version {self.version}, "
            f"{w.count('resent')} resent, {w.count('stale')} stale, "
            f"{w.count('implausible')} implausible, {w.count('restarts')} sim restarts, "
            f"{w.count('mismatch')} mismatched, {w.count('rejected')} rejected weights, "
            f"unpaired halves dropped: {drops['superseded']} superseded, "
            f"{drops['overflow']} overflow"
        )
        if self.rollouts is not None:
            line += (
                f"; {self.rollouts.sent} rollout chunks sent, {self.rollouts.unlearned} "
                f"steps served while no learner subscribed; partial chunks dropped: "
                f"{self.rollouts.assembler.dropped}"
            )
        return line
