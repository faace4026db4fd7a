"""The trainer's rollout source over Zenoh: announce the weights, gather one chunk from each
rollout worker, hand the learner their environments side by side.

Consumes `trainer/<w>/rollout` (RolloutChunk, `hamnet.trainer.storage.rollout_chunks`) from every worker
(DAgger: `trainer/<w>/demonstrations`, `hamnet.trainer.storage.demonstration_chunks`, the same way);
produces `trainer/weights` (WeightsAnnouncement with the schedule counter) once before every
rollout, and answers queries on that key with the current announcement, so a worker that
starts late (or missed one) asks for it instead of every worker receiving repeats. A chunk is checked on arrival (names, shapes, finite values, inputs the
policy can read); one that does not fit is dropped by the inbox (its first of each kind
logged with the reason) and counted in `dropped`.

On-policy by default: with `max_policy_lag` 0 a worker acts only with the newest weights
(it waits for each announcement) and the learner takes only chunks of its current version.
With a lag L > 0 workers keep acting while the learner updates and chunks up to L versions
old are learned from; older ones are dropped and counted (`dropped`). The learner's
environments are the workers' in the order of their worker ids, one chunk of each per
update, taken in the order each worker sent them, so the reward scaler sees every
environment's steps in sequence. Which workers an iteration waits for, and what happens when
one drops out, is `hamnet.trainer.collection.worker_roster.Roster`'s: the trainer follows the workers'
liveliness tokens (`alive/<service>/<w>`) on the service thread, with the chunks.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections import defaultdict, deque
from collections.abc import Callable

from hamnet.policy.policy import Policy
from hamnet.policy.rollout_record import merge_environments
from hamnet.runtime import contract
from hamnet.runtime.keys import check_segment, parse_alive_key
from hamnet.runtime.service import ALIVE, Service
from hamnet.trainer.collection.sources import Collected
from hamnet.trainer.collection.worker_roster import Roster
from hamnet.trainer.publisher import WEIGHTS, encode_weights
from hamnet.trainer.runners.ranks import ONE, Ranks
from hamnet.trainer.runners.stopping import always
from hamnet.trainer.storage.rollout_chunks import Arrived, chunk_decoder

log = logging.getLogger(__name__)

ROLLOUT = contract.topic("trainer/<w>/rollout")


def worker_of(key: str) -> str:
    """The worker id segment of a `trainer/<w>/rollout` key."""
    return check_segment("w", key.split("/")[-2])


class Streamed:
    """Rollouts from `workers` rollout workers (`hamnet rollout`), each with `envs_per_worker`
    environments acting `steps` steps per chunk."""

    def __init__(
        self,
        service: Service,
        policy: Policy,
        workers: int,
        envs_per_worker: int,
        max_policy_lag: int = 0,
        report_period_s: float = 10.0,
        ranks: Ranks = ONE,
        worker_timeout_s: float = math.inf,
        decoder: Callable[[Policy], Callable[[str, bytes], Arrived]] = chunk_decoder,
        topic: contract.Topic = ROLLOUT,
    ) -> None:
        """With several learner `ranks`, this one learns from the workers numbered 0 to
        `workers` - 1 that it owns (`Ranks.own`: id modulo the ranks), every one in every
        iteration, and only the main rank announces the weights and answers queries for them.
        With one rank a worker whose token goes away, or that sends nothing for
        `worker_timeout_s` after an iteration begins, drops out of it (`Roster`). Chunks come
        on `topic` (default `trainer/<w>/rollout`), read by `decoder(policy)` (PPO's rollouts; DAgger
        gives its demonstrations' topic and decoder)."""
        if workers < 1 or max_policy_lag < 0 or workers % ranks.size:
            raise ValueError(
                "workers must be >= 1, a multiple of the learner ranks, and max_policy_lag >= 0"
            )
        self.service, self.envs_per_worker = service, envs_per_worker
        self.workers = workers // ranks.size
        self.max_policy_lag, self.report_period_s = max_policy_lag, report_period_s
        ns, decode, self.topic = service.namespace, decoder(policy), topic
        self.roster = Roster(self.workers, envs_per_worker, ranks.size == 1, worker_timeout_s)
        service.inbox.watch("alive", ALIVE.pattern_in(ns))  # before the chunks: tokens first
        if ranks.size == 1:  # any worker ids
            keys = [topic.pattern_in(ns)]
        else:
            keys = [topic.key(ns, w=str(w)) for w in range(workers) if ranks.own(str(w))]
        for key in keys:
            service.inbox.subscribe("rollout", key, decoder=decode)
        self.weights = service.publisher(WEIGHTS.key(ns)) if ranks.main else None
        if ranks.main:
            service.inbox.serve("weights_query", WEIGHTS.key(ns))
        self.queues: dict[str, deque[Arrived]] = defaultdict(deque)
        """Fitting chunks per worker id, oldest first, each with its arrival (monotonic s)."""
        self.stale = 0
        """Fitting chunks dropped as too old or of the wrong size."""
        self.last_arrival: dict[str, float] = {}
        """When each worker's latest chunk learned from arrived (monotonic s)."""

    @property
    def num_envs(self) -> int:
        return self.workers * self.envs_per_worker

    @property
    def dropped(self) -> int:
        """Chunks dropped so far: too old or of the wrong size (`stale`), or refused by the
        decoder (unfit, another teacher's) or the full inbox (counted by the service)."""
        refused = sum(
            count
            for (key, _), count in list(self.service.drops.counts.items())
            if self.topic.matches(key)
        )
        return self.stale + refused

    @property
    def alone_in_update(self) -> bool:
        """Synchronous workers (`max_policy_lag` 0) wait for the new weights; with a lag
        allowed they act meanwhile."""
        return self.max_policy_lag == 0

    def collect(
        self,
        policy: Policy,
        steps: int,
        env_transitions: int,
        version: int,
        running: Callable[[], bool] = always,
    ) -> Collected:
        """Announce `policy` as `version`, then wait for a fitting chunk from each worker the
        iteration waits for (`Roster`), and learn from those queued; InterruptedError once
        the service or `running` stops."""
        announcement = encode_weights(policy, version, env_transitions, steps)
        if self.weights is not None:
            self.weights.put(announcement)
        announced = waiting_since = time.monotonic()
        self.roster.begin(announced)
        while self.service.running and running():
            self._drop_stale(version)
            ready = {worker for worker, queue in self.queues.items() if queue}
            taken = self.roster.takes(ready, time.monotonic())
            if taken is not None:
                return self._collected(taken, version, announced)
            if time.monotonic() - waiting_since >= self.report_period_s:
                log.info(
                    "waiting for rollouts of version %d from %s: start `hamnet rollout` "
                    "workers with this run's flags (%d chunks dropped so far)",
                    version,
                    sorted(self.roster.waiting) or f"{self.workers} workers",
                    self.dropped,
                )
                waiting_since = time.monotonic()
            received = self.service.receive(timeout=0.1)
            if received is None:
                continue
            if received.name == "weights_query" and self.weights is not None:
                self.weights.answer(received.value, announcement)
            elif received.name == "alive":
                _, service, worker = parse_alive_key(received.key)
                self.roster.token(f"{service}/{worker}", received.value)
            else:
                self._take(received.key, received.value, received.received_ns / 1e9, steps)
        raise InterruptedError("the trainer was stopped while waiting for rollouts")

    def _collected(self, taken: list[str], version: int, announced: float) -> Collected:
        """One queued chunk of each `taken` worker, side by side, with its figures."""
        arrived = [self.queues[worker].popleft() for worker in taken]
        transitions = self.envs_per_worker * len(arrived[0].rollout.dones)
        for worker, chunk in zip(taken, arrived, strict=True):
            since = max(announced, self.last_arrival.get(worker, announced))
            rate = transitions / max(chunk.arrived_s - since, 1e-9)
            self.roster.took(worker, version - chunk.version, rate)
            self.last_arrival[worker] = chunk.arrived_s
        lag = sum(version - chunk.version for chunk in arrived) / len(arrived)
        return Collected(
            merge_environments([chunk.rollout for chunk in arrived]),
            lag,
            self.dropped,
            self.roster.rows(taken),
            self.roster.metrics(),
        )

    def _take(self, key: str, chunk: Arrived, arrived_s: float, steps: int) -> None:
        """Queue a decoded chunk from the worker of `key` (arrived at `arrived_s`, monotonic
        s), unless it cannot join an update."""
        shape = tuple(chunk.rollout.dones.shape)
        if shape != (steps, self.envs_per_worker):
            self.stale += 1
            log.warning(
                "dropped a rollout from %s: %d steps of %d environments, the trainer "
                "learns from %d of %d",
                key,
                *shape,
                steps,
                self.envs_per_worker,
            )
            return
        worker = worker_of(key)
        self.roster.arrived(worker, chunk.source)
        self.queues[worker].append(dataclasses.replace(chunk, arrived_s=arrived_s))

    def _drop_stale(self, version: int) -> None:
        """Drop chunks acted more than `max_policy_lag` versions ago (or by future versions
        of an earlier run)."""
        for queue in self.queues.values():
            while queue and not 0 <= version - queue[0].version <= self.max_policy_lag:
                queue.popleft()
                self.stale += 1
