"""What a run learns by: the one interface the `Runner`, the rollout worker service and
`hamnet trainer` call, so PPO and DAgger share one loop, one rollout path and one command.

An algorithm is chosen before the run's policy exists (`hamnet.trainer.algorithms.choice`):
it says how the run must be configured (`prepare`), what its in-process collection is, which
chunks its rollout workers stream, and how its result is measured. `start` then gives it the
run's policy, as rsl_rl's runner hands its algorithm the storage once the environments are
known; from there it owns the optimizer and whatever else its update keeps, and learns from
each collected rollout.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import torch

from hamnet.policy.policy import Policy
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime import contract
from hamnet.trainer.collection.sources import Collected, RolloutSource
from hamnet.trainer.results.evaluate import HeldOut
from hamnet.trainer.runners.ranks import Ranks
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.snapshots import Arrays, Snapshot
from hamnet.trainer.runners.stopping import always
from hamnet.trainer.storage.rollout_chunks import Arrived


class Algorithm(Protocol):
    """PPO (`ppo_learner.PPO`) or DAgger (`dagger_learner.Dagger`)."""

    name: str
    """`--algo`'s value."""
    optimizer: torch.optim.Optimizer
    """Over the run's policy (set by `start`)."""

    def prepare(self, config: RunConfig) -> RunConfig:
        """The run as this algorithm runs it; ValueError (a one-line reason) when it cannot."""

    def in_process(self, config: RunConfig) -> RolloutSource:
        """The run's collection in this process (`hamnet trainer --inprocess`, a worker)."""

    @property
    def topic(self) -> contract.Topic:
        """Where rollout workers stream this algorithm's chunks."""

    def encode(self, rollout: Any, version: int, sequence: int) -> RolloutChunk:
        """A worker's chunk of one collected rollout acted by weights `version`."""

    def decoder(self, policy: Policy) -> Callable[[str, bytes], Arrived]:
        """The learner's check and decoder of this algorithm's chunks."""

    def start(self, policy: Policy, envs: int, ranks: Ranks, threads: int) -> None:
        """Take the run's `policy`, learning from `envs` environments (every rank's) on
        `threads` torch threads."""

    def learn(
        self,
        collected: Collected,
        whole: Any,
        env_transitions: int,
        running: Callable[[], bool] = always,
    ) -> dict[str, float]:
        """Learn from this rank's `collected` rollout (`whole`: every rank's), collected
        from the schedule counter `env_transitions`; the metrics of the update.
        InterruptedError once `running()` turns False."""

    def progress(self, row: dict[str, float]) -> str:
        """The progress line of an iteration's metrics."""

    def snapshot(self) -> Snapshot:
        """What the update keeps between iterations, to resume from."""

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from `snapshot`; ResumeError when it is not this algorithm's."""

    def held_out(
        self, policy: Policy, config: RunConfig, env_transitions: int
    ) -> tuple[HeldOut, dict[str, object]]:
        """The learned policy on `config.eval_episodes` held-out episodes, and what the
        run's summary adds about it."""

    def summary_fields(self) -> dict[str, object]:
        """What a summary records about the algorithm, evaluated or not."""
