"""A rollout worker's loop (`hamnet rollout`): act with the trainer's newest weights in B
in-process environments and stream each rollout as a RolloutChunk.

Consumes `trainer/weights` (WeightsAnnouncement: the weights, their version, the schedule
counter they act at and the rollout length the trainer learns from, which the worker acts
whatever its own `--steps-per-rollout`); produces `trainer/<w>/rollout` (RolloutChunk, header.policy_version =
the version that acted). The cores are the in-process trainer's (`InProcess`: VectorEnv,
Perception, the policy's input builder, the safety filter's training profile), so a worker
collects exactly what `hamnet trainer --inprocess` would. Worker k's environments are seeded
`seed + k * SEED_STRIDE`, so workers never repeat each other's episodes and worker 0 repeats
an in-process run.

What it collects and streams is its algorithm's (`hamnet.trainer.algorithms.algorithm`), the
trainer's: PPO's rollouts, or with `hamnet rollout --algo dagger --teacher CKPT` DAgger's
(`InProcessDagger`: the frozen teacher from the file, the student acting with the announced
weights, who acts drawn from beta at the announced counter), streamed as `Demonstrations` on
`trainer/<w>/demonstrations` (`hamnet.trainer.storage.demonstration_chunks`), each chunk
naming the teacher's SHA-256.

With `max_policy_lag` 0 (synchronous) a worker waits for a new announcement after each chunk;
with a lag it keeps acting with the newest weights it has (the trainer drops what is too
old). A bad announcement is logged and the worker keeps the weights it has. A chunk is put
only once a learner subscribes to its key: until then the worker holds it.
"""

from __future__ import annotations

import dataclasses
import logging
import time

from hamnet.policy.policy import Policy
from hamnet.policy.weights import (
    WeightsError,
    check_action_space,
    from_announcement,
    load_into,
    policy_from,
)
from hamnet.proto.trainer_pb2 import RolloutChunk, WeightsAnnouncement
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.service import Service
from hamnet.trainer.algorithms.algorithm import Algorithm
from hamnet.trainer.algorithms.ppo_learner import PPO
from hamnet.trainer.publisher import WEIGHTS
from hamnet.trainer.runners.run_config import RunConfig

log = logging.getLogger(__name__)

ASK_AFTER_S = 5.0
"""A worker waiting this long for new weights asks the trainer for its current ones."""

SEED_STRIDE = 100_003
"""Seed distance between two workers' environments (a prime far above any group offset)."""


def worker_config(config: RunConfig, worker: str) -> RunConfig:
    """The run as worker `worker` (a number) collects it: its own seed."""
    if not worker.isdigit():
        raise ValueError(
            f"a rollout worker's id must be a number (it offsets the seed), got {worker!r}"
        )
    sim = dataclasses.replace(config.sim, seed=config.seed + int(worker) * SEED_STRIDE)
    return dataclasses.replace(config, sim=sim)


class RolloutService:
    """One worker: in-process cores, the newest weights, a chunk per rollout."""

    def __init__(
        self,
        service: Service,
        config: RunConfig,
        max_policy_lag: int = 0,
        report_period_s: float = 10.0,
        algorithm: Algorithm | None = None,
    ) -> None:
        """Collect as `algorithm` does (default PPO; DAgger's worker draws who acts from its
        beta schedule: give it the trainer's). ValueError when it cannot run `config`."""
        self.algorithm = PPO(config) if algorithm is None else algorithm
        config = self.algorithm.prepare(config)
        self.service, self.config, self.max_policy_lag = service, config, max_policy_lag
        self.report_period_s = report_period_s
        ns, worker = service.namespace, service.identity.worker
        self.source = self.algorithm.in_process(worker_config(config, worker))
        service.inbox.subscribe("weights", WEIGHTS.key(ns), WeightsAnnouncement)
        self.chunks = service.publisher(self.algorithm.topic.key(ns, w=worker))
        self.policy: Policy | None = None
        self.version = 0
        """Version of the weights held (0: none yet)."""
        self.acted = 0
        """Version that acted in the last chunk sent (0: none sent)."""
        self.env_transitions = 0
        self.rollout_steps = 0
        """T the trainer's announcements ask for (0: none has; the run's own)."""
        self.sent = self.rejected = 0

    def run(self) -> None:
        """Collect and send until stopped."""
        report = LoopReport(self.report_period_s, self._line, logger=log)
        while self.service.running:
            report.tick()
            self._take_weights(
                wait=self.policy is None
                or (self.max_policy_lag == 0 and self.version == self.acted)
            )
            if self.policy is None or not self.service.running:
                continue
            steps, started = self.rollout_steps or self.config.rollout_steps, time.monotonic()
            try:  # a stopped worker leaves its unfinished chunk at once
                collected = self.source.collect(
                    self.policy,
                    steps,
                    self.env_transitions,
                    self.version,
                    lambda: self.service.running,
                )
            except InterruptedError:
                break
            self._send(self.algorithm.encode(collected.rollout, self.version, self.sent))
            self.sent, self.acted = self.sent + 1, self.version
            self.env_transitions += steps * self.source.num_envs  # runs on between updates
            report.count("env_steps", steps * self.source.num_envs)
            report.count("acting_s", time.monotonic() - started)

    def _line(self, w: Window) -> str:
        """The rate line: env steps/s while acting, and the share of the time spent acting."""
        rate = w.count("env_steps") / max(w.count("acting_s"), 1e-9)
        return (
            f"{self.sent} rollouts sent, weights version {self.version}, {rate:.0f} env "
            f"steps/s while acting ({100 * w.rate('acting_s'):.0f}% of the time), "
            f"{self.rejected} bad announcements"
        )

    def _send(self, chunk: RolloutChunk) -> None:
        """Put `chunk` once a learner subscribes to it. Put before then, it would reach no one,
        and a synchronous worker would wait for weights that its learner cannot announce
        without the chunk: a learner rank whose subscription had not yet reached this worker
        hung a run that way. The hold is counted (`chunks_held_for_a_learner`)."""
        if not self.chunks.matching:
            self.service.count_event("chunks_held_for_a_learner")
            log.info(
                "holding a rollout of version %d until a learner subscribes to %s",
                self.version,
                self.chunks.key,
            )
            while not self.chunks.matching and self.service.running:
                self.service.heartbeat()
                time.sleep(0.05)
        self.chunks.put(chunk)

    def _take_weights(self, wait: bool) -> None:
        """Load the newest announcement waiting (with `wait`, block until one newer than the
        weights held arrives, or a stop). Without weights, or after `ASK_AFTER_S` of waiting
        (a restarted or resumed trainer, a missed announcement), ask the trainer for its
        current ones and act with them even when their version is the one held: a trainer
        resumed while it waited for that version's rollouts needs them again."""
        newest, started = None, time.monotonic()
        while self.service.running:
            received = self.service.receive(timeout=0.1 if wait and newest is None else 0.0)
            if received is None:
                if newest is not None or not wait:
                    break
                if self.policy is None or time.monotonic() - started >= ASK_AFTER_S:
                    self.service.inbox.catch_up("weights", WEIGHTS.key(self.service.namespace))
                continue
            if received.value.version != self.version or time.monotonic() - started >= ASK_AFTER_S:
                newest = (
                    received.value
                )  # the same version after a long wait: a resumed trainer wants it again
        if newest is not None:
            self._load(newest)

    def _load(self, message: WeightsAnnouncement) -> None:
        try:
            weights = from_announcement(message)
            check_action_space(weights, self.config.action_space)
            if self.policy is None:
                self.policy = policy_from(weights)
            else:
                load_into(self.policy, weights)
        except WeightsError as error:
            self.rejected += 1
            log.error(
                "rejected weights version %d: %s; keeping version %d",
                message.version,
                error,
                self.version,
            )
            return
        self.version, self.env_transitions = message.version, message.env_transitions
        self.rollout_steps = message.rollout_steps or self.rollout_steps
