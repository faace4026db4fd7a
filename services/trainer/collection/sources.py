"""Where a run's rollouts come from: the `RolloutSource` protocol the runner collects
through, what one collection hands back (`Collected`), and the in-process source
(`InProcess`: the sim, perception, policy and the safety filter's training profile in this
process, `hamnet trainer --inprocess`). The streamed source over Zenoh is
`hamnet.trainer.collection.streamed`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import torch

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.perception.checkpoint import load_checkpoint
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import Perception
from hamnet.perception.unicorn import UniCORN
from hamnet.policy.policy import Policy
from hamnet.policy.registry import architecture
from hamnet.policy.rollout_record import Rollout
from hamnet.safety.config import SafetyConfig, in_action_space, with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.env import VectorEnv
from hamnet.trainer.collection.rollout_worker import RolloutWorker, collect_overlapped
from hamnet.trainer.collection.scripted_pusher import ScriptedPusher
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.snapshots import Arrays, Snapshot, nest, part
from hamnet.trainer.runners.stopping import always


def frozen_encoder(config: RunConfig) -> tuple[UniCORN, int]:
    """The run's frozen UniCORN and its version: `encoder_checkpoint`'s, or (version 0) a
    random one drawn from the run's seed, so every encoder a run builds (its workers', the
    held-out evaluation's) is the same."""
    if config.random_encoder:
        torch.manual_seed(config.seed)
        encoder, version = UniCORN(), 0
    else:
        encoder, version = load_checkpoint(config.encoder_checkpoint)
    return encoder.requires_grad_(False), version


def run_clouds(config: RunConfig, clouds: CloudConfig | None = None) -> CloudConfig:
    """`clouds` (default: every surface, noise-free) with the encoder at the run's
    `encoder_precision`."""
    clouds = clouds if clouds is not None else CloudConfig()
    return dataclasses.replace(clouds, encoder_precision=config.encoder_precision)


def build_workers(
    config: RunConfig,
    groups: int,
    clouds: CloudConfig | None = None,
    encoder: tuple[UniCORN, int] | None = None,
    safety: SafetyConfig | None = None,
) -> tuple[list[RolloutWorker], int]:
    """The in-process cores of the run, in `groups` groups of environments (each its own
    sim, perception caches and filter), and the encoder's version (0: random weights; no
    perception at all for a policy without clouds). The groups share one frozen encoder:
    `encoder` when given, else `frozen_encoder(config)`; perception samples `clouds`
    (default: every surface, noise-free); the safety filter is `safety` (default: the
    training profile) reading actions in the run's `action_space`; a guided run's workers
    record the scripted pusher's actions (`GuideConfig`)."""
    size = config.num_envs // groups
    frozen, version = None, 0
    if architecture(config.architecture).config.clouds:
        frozen, version = frozen_encoder(config) if encoder is None else encoder
    threads = 1 if groups > 1 else config.sim.nthread  # the other core runs the networks
    safety = in_action_space(
        with_profile("training") if safety is None else safety, config.action_space
    )
    workers, seen = [], run_clouds(config, clouds)
    for group in range(groups):
        seed = config.seed + group
        env = VectorEnv(dataclasses.replace(config.sim, num_envs=size, seed=seed, nthread=threads))
        perception = None if frozen is None else Perception(frozen, size, seen, seed=seed)
        safe = SafetyFilter(np.zeros((size, NUM_JOINTS)), safety)
        guide = ScriptedPusher(env, safety.action_magnitude) if config.guide.coef else None
        workers.append(RolloutWorker(env, perception, safe, seed, guide))
    return workers, version


@dataclass(frozen=True)
class Collected:
    """One rollout for an update, with how fresh it was."""

    rollout: Rollout
    policy_lag: float = 0.0
    """Mean number of updates between the weights that acted and the learner's."""
    dropped: int = 0
    """Rollouts dropped so far as too stale or unfit."""
    envs: torch.Tensor | None = None
    """(B,) which of the source's environments the rollout holds, in its order (some rollout
    workers dropped out); None: all of them."""
    figures: dict[str, float] = field(default_factory=dict)
    """The source's own metrics of the iteration (per rollout worker)."""


class RolloutSource(Protocol):
    """Where a run's rollouts come from."""

    @property
    def num_envs(self) -> int:
        """B: environments of every rollout, in a fixed order."""

    @property
    def alone_in_update(self) -> bool:
        """Whether its environments wait while the trainer learns, so the update may take
        every core (`RunConfig.learner_threads`)."""

    def collect(
        self,
        policy: Policy,
        steps: int,
        env_transitions: int,
        version: int,
        running: Callable[[], bool] = always,
    ) -> Collected:
        """T = `steps` steps of every environment, acted by `policy` (weights `version`,
        its log std set for the counter `env_transitions`) or by an older version of it;
        InterruptedError once `running()` turns False before it is complete."""


class InProcess:
    """Rollouts from `RolloutWorker`s in this process (in two overlapped groups when the
    run says so): no messages, nothing stale."""

    def __init__(self, config: RunConfig) -> None:
        self.overlapped = config.overlapped
        self.workers, self.encoder_version = build_workers(config, 2 if config.overlapped else 1)

    @property
    def num_envs(self) -> int:
        return sum(worker.env.num_envs for worker in self.workers)

    @property
    def alone_in_update(self) -> bool:
        return True

    def snapshot(self) -> Snapshot:
        """Every worker's whole state (`RolloutWorker.snapshot`), as `worker<i>`."""
        return nest({f"worker{i}": worker.snapshot() for i, worker in enumerate(self.workers)})

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from `snapshot` (workers built from the same config)."""
        for i, worker in enumerate(self.workers):
            worker.restore(*part(arrays, meta, f"worker{i}"))

    def collect(
        self,
        policy: Policy,
        steps: int,
        env_transitions: int,
        version: int,
        running: Callable[[], bool] = always,
    ) -> Collected:
        if self.overlapped:
            return Collected(
                collect_overlapped(tuple(self.workers), policy, steps, env_transitions, running)
            )
        return Collected(self.workers[0].collect(policy, steps, env_transitions, running=running))
