"""The training loop: collect a rollout, compute per-term advantages, update PPO, advance
the one schedule counter, log, checkpoint.

Rollouts come from a `RolloutSource`: `InProcess` runs the sim, perception, policy and the
safety filter's training profile through `RolloutWorker` in this process
(`hamnet trainer --inprocess`); `hamnet.trainer.stream.Streamed` announces the weights and
gathers chunks from rollout workers over Zenoh (`hamnet trainer`). Either way one loop learns. Rewards are
scaled by the running std of the summed return before GAE (`ReturnScaler`), and the
bootstrap of truncated episodes is added after scaling, since values live in scaled units.
The policy's input statistics (`InputNormalizer`, saved with its weights) take in each
rollout's observations after the update.
Per iteration one JSON line goes to `<run_dir>/metrics.jsonl`; a progress line goes to the
log every `log_period_s`. Shapes: T steps, B environments, R reward terms.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import logging
import math
import os
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.perception.checkpoint import SHIPPED_ENCODER, load_checkpoint
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import Perception
from hamnet.perception.unicorn import UniCORN
from hamnet.policy.config import Initialization, LogStdConfig
from hamnet.policy.policy import Policy
from hamnet.policy.registry import architecture, build, with_changes
from hamnet.policy.weights import load_into, read_checkpoint, save_checkpoint
from hamnet.runtime.compute import torch_threads
from hamnet.safety.config import with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.rewards import REWARD_NAMES
from hamnet.sim.stages import STAGES, StageName, stage_config
from hamnet.trainer import resume
from hamnet.trainer.config import PPOConfig
from hamnet.trainer.gae import gae
from hamnet.trainer.losses import energy_loss
from hamnet.trainer.normalization import ReturnScaler
from hamnet.trainer.ppo import Batch, UpdateStats, optimizer_for, update
from hamnet.trainer.ranks import ONE, Ranks
from hamnet.trainer.resume import Arrays, Resumable, ResumeError, Snapshot, nest, part
from hamnet.trainer.rollout import RolloutWorker, collect_overlapped
from hamnet.trainer.stopping import always
from hamnet.trainer.trajectory import Rollout
from hamnet.trainer.workers import progress as workers_progress

log = logging.getLogger(__name__)


NUM_ENVS = 64
"""Environments of a run unless `--sim.num-envs` says otherwise."""


def stage_sim(stage: StageName) -> SimConfig:
    """The environments of a run on `stage`: the stage with `NUM_ENVS` environments."""
    return stage_config(stage, num_envs=NUM_ENVS)


@dataclass(frozen=True)
class RunConfig:
    """One training run in one process."""

    stage: StageName = "easy"
    """Training stage (`hamnet.sim.stages`): full, easy or easy-5cm (the former easy stage).
    It sets the defaults of every `--sim.*` flag; those flags change any field on top of it."""
    sim: SimConfig = field(default_factory=lambda: stage_sim("easy"))
    """The environments: count (`--sim.num-envs`, default 64), seed of the sim, the networks
    and the action noise (`--sim.seed`), physics threads without `overlap`
    (`--sim.nthread`), scenes, placement, task and curriculum: the stage's, with any change."""
    architecture: str = "hamnet"
    """Policy architecture (`hamnet policy --print-params` lists them)."""
    workers: int = 1
    """Rollout workers (`hamnet rollout`) whose chunks make one update, `--sim.num-envs`
    environments each (1 in-process). A trainer's own: its workers act as many steps as its
    announcements ask (`WeightsAnnouncement.rollout_steps`)."""
    samples_per_update: int = 8192
    """Env transitions each update learns from, T x environments x workers: the authors'
    1024 environments x 8 steps (rss_train.yaml:10, 166). It sets T unless
    `--steps-per-rollout` does: at 64 environments T = 128. Tied to the environment count
    (64 x 8 = 512), two independent batches' actor gradients agree at cosine 0.01-0.03 and
    each update spends its KL on noise (docs/trainer.md)."""
    steps_per_rollout: int = 0
    """T: policy steps per environment between two updates; 0: samples_per_update /
    (environments x workers). The authors' `rollout_size: 8` (rss_train.yaml:166, the
    paper's "update frequency 8") is their 8192 samples at 1024 environments."""
    max_env_transitions: int = 2_048_000_000
    """Stop after this many env_transitions (the authors' 2e6 vectorized steps of 1024)."""
    max_wall_clock_s: float = math.inf
    """Stop after this much wall-clock time, s."""
    run_dir: Path = Path("runs/train")
    """Where metrics.jsonl and checkpoints go."""
    encoder_checkpoint: Path = SHIPPED_ENCODER
    """UniCORN weights, frozen while the policy learns (the paper's); default: the
    pre-trained encoder shipped in the package."""
    random_encoder: bool = False
    """Freeze a randomly initialised encoder (version 0) instead: the ablation without
    pre-training."""
    overlap: bool | None = None
    """Split the environments into two groups and step one group's physics while the other's
    perception, policy and safety run (`rollout.collect_overlapped`), so both cores stay
    busy; None: when the policy reads clouds (1.18x for HAMnet at 64 environments in
    `benchmarks/training.py`; a policy without perception is faster on all physics threads)."""
    learner_threads: int = 0
    """Torch threads of the PPO update; 0: when the environments wait for it (in process, or
    synchronous workers, `--max-policy-lag` 0), every core, shared among learner ranks
    (1.6-1.8x faster updates than one thread on the 2-core machine, `benchmarks/learner.py`);
    else 1. Set 1 where other services share the cores: the demo's stack of seven services
    on 2 cores ran its tiny updates too slowly with two threads."""
    log_period_s: float = 10.0
    """Seconds between two progress lines."""
    checkpoint_period_s: float = 600.0
    """Seconds between two checkpoints (one more is written at the end)."""
    eval_episodes: int = 64
    """Held-out episodes the final policy plays with its mean (`final_success_rate`); 0: none."""
    ppo: PPOConfig = field(default_factory=PPOConfig)
    init: Initialization = "orthogonal"
    """How the actor and critic start: orthogonal (output layers 0.01 and 1) or torch's
    default, the authors' (`hamnet.policy.init`)."""
    shared_value_gradient: bool = False
    """HAMnet: the value loss trains the layers actor and critic share too (the authors');
    default: the critic reads them with their gradient stopped
    (`ModelConfig.shared_value_gradient`, docs/trainer.md)."""
    log_std: LogStdConfig = field(default_factory=LogStdConfig)
    """The actor's log std: learned from -0.5 (default), or a schedule over env_transitions
    (`--log-std.mode schedule`: the authors' -0.4 minus 0.000367 per 1024 x 1024
    transitions, which spans their 2e9; `--log-std.horizon N` shrinks it to
    `--log-std.final` within N transitions). The weights carry it to every policy that acts."""

    @property
    def overlapped(self) -> bool:
        """Whether the run collects in two overlapped groups (`overlap`, resolved)."""
        if self.overlap is None:
            return architecture(self.architecture).config.clouds
        return self.overlap

    @property
    def num_envs(self) -> int:
        """B: environments stepped together (the sim's)."""
        return self.sim.num_envs

    @property
    def rollout_steps(self) -> int:
        """T of every rollout: `steps_per_rollout`, or derived from `samples_per_update`."""
        if self.steps_per_rollout:
            return self.steps_per_rollout
        return max(1, self.samples_per_update // (self.num_envs * self.workers))

    @property
    def seed(self) -> int:
        """Seed of the sim, the networks and the action noise (the sim's)."""
        return self.sim.seed

    @property
    def identity(self) -> dict[str, object]:
        """What a resumed run must share with its snapshot: the networks' shapes, the
        environments and the rollout length (the PPO settings and budgets may change)."""
        return {
            "architecture": self.architecture, "sim": self.sim,
            "steps_per_rollout": self.rollout_steps, "overlapped": self.overlapped,
        }  # fmt: skip

    def __post_init__(self) -> None:
        if self.stage not in STAGES:
            raise ValueError(f"unknown stage {self.stage!r}; stages: {', '.join(STAGES)}")
        if self.steps_per_rollout < 0 or self.samples_per_update < 1 or self.workers < 1:
            raise ValueError("steps_per_rollout must be >= 0, samples_per_update and workers >= 1")
        if self.overlapped and self.num_envs % 2:
            raise ValueError("overlap splits the environments in two groups: num_envs must be even")
        if self.eval_episodes < 0 or self.learner_threads < 0:
            raise ValueError("eval_episodes and learner_threads must be >= 0")


class EpisodeTracker:
    """Returns per reward term, lengths and outcomes of the episodes that ended."""

    def __init__(self, num_envs: int, num_terms: int, window: int = 200) -> None:
        self.returns = np.zeros((num_envs, num_terms))
        self.lengths = np.zeros(num_envs, dtype=np.int64)
        self.finished: deque[tuple[np.ndarray, int, bool]] = deque(maxlen=window)
        """The last `window` episodes: (returns (R,), length, success)."""

    def add(self, rollout: Rollout, envs: torch.Tensor | None = None) -> None:
        """Fold in T steps of sim rewards and ends of the environments `envs` (B,) (None:
        all, in order)."""
        rewards, dones, success = (
            rollout.rewards.numpy(),
            rollout.dones.numpy(),
            rollout.success.numpy(),
        )
        rows = np.arange(len(self.lengths)) if envs is None else envs.numpy()  # (B,)
        for t in range(len(rewards)):
            self.returns[rows] += rewards[t]
            self.lengths[rows] += 1
            for i in np.flatnonzero(dones[t]):
                env = rows[i]
                self.finished.append(
                    (self.returns[env].copy(), int(self.lengths[env]), bool(success[t, i]))
                )
                self.returns[env], self.lengths[env] = 0.0, 0

    def snapshot(self) -> Snapshot:
        """Running returns and lengths (B, ...) and the recorded episodes, for `restore`."""
        finished, width = list(self.finished), self.returns.shape[1]  # E episodes, R terms
        arrays = {
            "returns": self.returns, "lengths": self.lengths,
            "finished.returns": np.array([r for r, _, _ in finished]).reshape(len(finished), width),
            "finished.lengths": np.array([n for _, n, _ in finished], dtype=np.int64),
            "finished.success": np.array([s for _, _, s in finished], dtype=bool),
        }  # fmt: skip
        return arrays, {}

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from `snapshot`'s arrays."""
        self.returns[...], self.lengths[...] = arrays["returns"], arrays["lengths"]
        self.finished.clear()
        returns, lengths = arrays["finished.returns"], arrays["finished.lengths"]
        records = zip(returns, lengths, arrays["finished.success"])
        self.finished.extend((np.array(r), int(n), bool(s)) for r, n, s in records)

    def summary(self) -> dict[str, float]:
        """Means over the recorded episodes (NaN before the first one ends)."""
        if not self.finished:
            return {"episodes": 0, "success_rate": math.nan, "episode_length": math.nan}
        returns = np.stack([r for r, _, _ in self.finished])  # (E, R)
        out = {f"return/{name}": float(returns[:, i].mean()) for i, name in enumerate(REWARD_NAMES)}
        out["return/total"] = float(returns.sum(1).mean())
        out["episodes"] = len(self.finished)
        out["success_rate"] = float(np.mean([s for _, _, s in self.finished]))
        out["episode_length"] = float(np.mean([n for _, n, _ in self.finished]))
        return out


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


def build_workers(
    config: RunConfig,
    groups: int,
    clouds: CloudConfig | None = None,
    encoder: tuple[UniCORN, int] | None = None,
) -> tuple[list[RolloutWorker], int]:
    """The in-process cores of the run, in `groups` groups of environments (each its own
    sim, perception caches and filter), and the encoder's version (0: random weights; no
    perception at all for a policy without clouds). The groups share one frozen encoder:
    `encoder` when given, else `frozen_encoder(config)`; perception samples `clouds`
    (default: every surface, noise-free)."""
    size = config.num_envs // groups
    frozen, version = None, 0
    if architecture(config.architecture).config.clouds:
        frozen, version = frozen_encoder(config) if encoder is None else encoder
    threads = 1 if groups > 1 else config.sim.nthread  # the other core runs the networks
    workers = []
    for group in range(groups):
        seed = config.seed + group
        env = VectorEnv(dataclasses.replace(config.sim, num_envs=size, seed=seed, nthread=threads))
        perception = None if frozen is None else Perception(frozen, size, clouds, seed=seed)
        safety = SafetyFilter(np.zeros((size, NUM_JOINTS)), with_profile("training"))
        workers.append(RolloutWorker(env, perception, safety, seed))
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
        self, policy: Policy, steps: int, env_transitions: int, version: int,
        running: Callable[[], bool] = always,
    ) -> Collected:  # fmt: skip
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
        self, policy: Policy, steps: int, env_transitions: int, version: int,
        running: Callable[[], bool] = always,
    ) -> Collected:  # fmt: skip
        if self.overlapped:
            return Collected(
                collect_overlapped(tuple(self.workers), policy, steps, env_transitions, running)
            )
        return Collected(self.workers[0].collect(policy, steps, env_transitions, running=running))


class Runner:
    """Owns the run: rollout source, policy, optimizer, reward scaler, counters."""

    def __init__(
        self,
        config: RunConfig,
        source: Callable[[Policy], RolloutSource] | None = None,
        resume: bool = False,
        ranks: Ranks = ONE,
    ) -> None:
        """`source(policy)` makes the rollout source for the run's policy (default `InProcess`).
        With `resume`, continue from the snapshot in `config.run_dir` (`hamnet.trainer.resume`);
        ResumeError when there is none or it is of another run, before anything is built.
        With several `ranks` this process learns from its source's environments, the others
        from theirs (`hamnet.trainer.ranks`); only the main rank writes metrics and checkpoints."""
        self.config, self.ranks = config, ranks
        saved = read_snapshot(config) if resume else None
        torch.set_num_threads(1)
        self.policy = build(
            config.architecture,
            with_changes(config.architecture, log_std=config.log_std, init=config.init,
                         shared_value_gradient=config.shared_value_gradient),
            config.seed,
        )
        self.source = InProcess(config) if source is None else source(self.policy)
        cores = max(1, (os.cpu_count() or 1) // ranks.size)  # ranks share the machine
        self.learner_threads = config.learner_threads or (cores if self.source.alone_in_update else 1)
        """Torch threads of the update (`RunConfig.learner_threads`, resolved)."""
        # After the source: every rank subscribes to its workers' chunks before the main one
        # announces the first weights.
        ranks.broadcast(self.policy)
        self.optimizer = optimizer_for(
            self.policy.actor_parameters(), self.policy.critic_parameters(), config.ppo
        )
        self.shuffle = torch.Generator().manual_seed(config.seed)
        """Draws the update's minibatches: its own stream, so a run from rollout workers
        shuffles as the same run in one process does (whose cores draw from torch's)."""
        self.energy = partial(energy_loss, config=with_profile("training").action_magnitude)
        """The energy loss of an action mean, read as the workers' safety profile reads it."""
        envs = self.source.num_envs * ranks.size  # every rank's: they see them all
        self.scaler = ReturnScaler(envs, config.ppo.gamma)
        self.tracker = EpisodeTracker(envs, len(REWARD_NAMES))
        self.env_transitions = 0
        self.iteration = 0
        self.wall_clock_s = 0.0
        """Wall-clock time of the run at its latest iteration, over every resume, s."""
        self.last_row: dict[str, float] = {}
        """The metrics of the latest iteration (empty before the first)."""
        self.interrupted = False
        """The last `run` was stopped in the middle of an iteration (and went back to its
        start) or while waiting for workers."""
        self.action_bounds = (
            -torch.ones(self.policy.config.action_dim),
            torch.ones(self.policy.config.action_dim),
        )
        config.run_dir.mkdir(parents=True, exist_ok=True)
        self.metrics_path = config.run_dir / "metrics.jsonl"
        if saved is not None:
            self.restore(*saved)

    @property
    def version(self) -> int:
        """Version of the current weights: the updates made so far plus one."""
        return self.iteration + 1

    def iterate(self, running: Callable[[], bool] = always) -> dict[str, float]:
        """One rollout and one PPO update; returns that iteration's metrics. A fresh run's
        first rollout only fills the input statistics (its actions saw zeros), so every
        action learned from saw standardised inputs. InterruptedError, with the iteration
        half done, once `running()` turns False (`run` goes back to before it)."""
        started = time.perf_counter()
        config, policy = self.config, self.policy
        policy.set_env_transitions(self.env_transitions)
        policy.eval()
        collected = self.source.collect(
            policy, config.rollout_steps, self.env_transitions, self.version, running
        )
        rollout = collected.rollout
        collect_done = time.perf_counter()
        whole = self.ranks.environments(rollout)
        self.tracker.add(whole, collected.envs)
        if policy.normalizer.count:
            stats = self.learn(rollout, whole, collected.envs, running)
        else:
            self.scaler_warm_up(whole, collected.envs)
            stats = UpdateStats.none(self.optimizer.param_groups[0]["lr"])
        policy.normalizer.update(whole.inputs.observation)  # after: act and evaluate agreed
        transitions = whole.actions.shape[0] * whole.actions.shape[1]
        return {
            **self.advance(transitions, started, collect_done),
            "log_std": float(policy.log_std.detach().mean()),
            **dataclasses.asdict(stats),
            "policy_lag": collected.policy_lag,
            "dropped_rollouts": collected.dropped,
            **collected.figures,
            **self.tracker.summary(),
        }

    def advance(self, transitions: int, started: float, collected: float) -> dict[str, float]:
        """Count an iteration of `transitions` env transitions; returns its counters and
        timing (`started`, `collected`: `time.perf_counter()` at its start and once its
        rollout was in)."""
        self.env_transitions += transitions
        self.iteration += 1
        done = time.perf_counter()
        return {
            "iteration": self.iteration,
            "env_transitions": self.env_transitions,
            "env_steps_per_s": transitions / (done - started),
            "collect_s": collected - started,
            "learn_s": done - collected,
        }

    def scaler_warm_up(self, whole: Rollout, envs: torch.Tensor | None) -> None:
        """Fold a rollout that is not learned from into the reward scaler's statistics."""
        for t in range(len(whole.rewards)):
            self.scaler.scale(whole.rewards[t], whole.dones[t], envs)

    def learn(
        self,
        rollout: Rollout,
        whole: Rollout | None = None,
        envs: torch.Tensor | None = None,
        running: Callable[[], bool] = always,
    ) -> UpdateStats:
        """One PPO update of this rank's `rollout` (`batch`), on `learner_threads` threads,
        the critic alone on features computed once after the actor stops (`ppo.update`);
        `running` stops it."""
        batch = self.batch(rollout, whole, envs)
        self.policy.train()
        with torch_threads(self.learner_threads):
            return update(
                self.policy.evaluate,
                self.policy.parameters(),
                self.optimizer,
                batch,
                self.action_bounds,
                self.config.ppo,
                generator=self.shuffle,
                energy=self.energy,
                ranks=self.ranks,
                running=running,
                critic=self.policy if self.policy.reads_value_features else None,
            )

    def batch(
        self, rollout: Rollout, whole: Rollout | None = None, envs: torch.Tensor | None = None
    ) -> Batch:
        """Scale rewards, bootstrap, GAE per term: the update's batch of this rank's
        `rollout`; `whole` (default `rollout`): every rank's environments, which the scaler
        sees; `envs`: which environments they are (None: all)."""
        whole = rollout if whole is None else whole
        scaled = torch.stack([self.scaler.scale(whole.rewards[t], whole.dones[t], envs)
                              for t in range(len(whole.rewards))])  # fmt: skip
        envs = rollout.rewards.shape[1]
        scaled = scaled[:, self.ranks.rank * envs : (self.ranks.rank + 1) * envs]  # this rank's
        rewards = scaled + self.config.ppo.gamma * rollout.final_values  # (T, B, R)
        ppo = self.config.ppo
        advantages, returns = gae(rewards, rollout.values, rollout.next_values, rollout.dones,
                                  ppo.gamma, ppo.gae_lambda)  # fmt: skip
        flat = lambda x: x.reshape(-1, *x.shape[2:])
        robot_state = rollout.inputs.observation.base[
            :, self.policy.config.observation.columns("base", "robot_state")
        ]
        return Batch(
            rollout.inputs,
            flat(rollout.actions),
            flat(rollout.log_prob),
            flat(advantages),
            flat(returns),
            joint_velocity=robot_state[:, NUM_JOINTS:],  # (T * B, J): q, then dq
        )

    def progress(self, row: dict[str, float]) -> str:
        """The progress line of an iteration's metrics."""
        return progress_line(row)

    @property
    def checkpoints(self) -> Path:
        """Where the run's checkpoint and snapshot go."""
        return self.config.run_dir / "checkpoints"

    def checkpoint(self) -> Path:
        """Write the policy's weights (loadable by `hamnet policy --checkpoint`) and the rest
        of the run's snapshot (`hamnet.trainer.resume`); returns the weights' path."""
        path = self.checkpoints / "latest.safetensors"
        path.parent.mkdir(parents=True, exist_ok=True)
        resume.write(self.checkpoints, self.snapshot())
        save_checkpoint(path, self.policy, self.version)
        return path

    def snapshot(self) -> Snapshot:
        """Everything but the policy's weights that the run continues from: Adam's state and
        learning rate, reward scaler, episode tracker, torch's global RNG and the minibatches'
        generator, counters, the run's
        identity and, from an in-process source, every worker's state."""
        parts = {
            "optimizer": resume.optimizer_snapshot(self.optimizer),
            "scaler": self.scaler.snapshot(),
            "tracker": self.tracker.snapshot(),
            "torch": ({"rng": torch.get_rng_state(), "shuffle": self.shuffle.get_state()}, {}),
        }
        if isinstance(self.source, Resumable):  # streamed: the workers simply go on
            parts["source"] = self.source.snapshot()
        arrays, meta = nest(parts)
        counters = {"iteration": self.iteration, "env_transitions": self.env_transitions,
                    "wall_clock_s": self.wall_clock_s}  # fmt: skip
        return arrays, {**meta, "counters": counters, "run": resume.as_json(self.config.identity)}

    def state(self) -> Snapshot:
        """The whole run in memory, copied: its snapshot and the policy's weights."""
        arrays, meta = self.snapshot()
        weights = {f"policy.{name}": value for name, value in self.policy.state_dict().items()}
        copied = {name: value.clone() if isinstance(value, torch.Tensor) else np.array(value)
                  for name, value in {**arrays, **weights}.items()}  # fmt: skip
        return copied, copy.deepcopy(meta)

    def load_state(self, state: Snapshot) -> None:
        """Go back to `state` (from `state()`): the weights, then the snapshot's parts."""
        arrays, meta = state
        prefix = "policy."
        self.policy.load_state_dict({name[len(prefix):]: value for name, value in arrays.items()
                                     if name.startswith(prefix)})  # fmt: skip
        rest = {name: value for name, value in arrays.items() if not name.startswith(prefix)}
        self.restore_parts({name: np.asarray(value) for name, value in rest.items()}, meta)

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from a snapshot of this run and the weights beside it; metrics rows written
        after the snapshot are dropped.

        Raises:
            ResumeError: the weights are missing or not the snapshot's, or a part does not fit.
        """
        iteration = meta["counters"]["iteration"]
        try:
            weights = read_checkpoint(self.checkpoints / "latest.safetensors")
            if weights.version != iteration + 1:
                raise ResumeError(f"weights of version {weights.version}, the snapshot is of "
                                  f"iteration {iteration} (a write was cut short)")  # fmt: skip
            load_into(self.policy, weights)
        except ValueError as error:
            raise ResumeError(f"cannot resume {self.config.run_dir}: {error}") from None
        self.restore_parts(arrays, meta)
        if self.ranks.main:
            resume.trim_metrics(self.metrics_path, self.iteration)

    def restore_parts(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Everything of a snapshot but the weights: optimizer, scaler, tracker, source,
        random generators and counters (ResumeError when a part does not fit)."""
        counters = meta["counters"]
        try:
            resume.restore_optimizer(self.optimizer, *part(arrays, meta, "optimizer"))
            self.scaler.restore(*part(arrays, meta, "scaler"))
            self.tracker.restore(*part(arrays, meta, "tracker"))
            if "source" in meta and isinstance(self.source, Resumable):
                self.source.restore(*part(arrays, meta, "source"))
        except ValueError as error:
            raise ResumeError(f"cannot resume {self.config.run_dir}: {error}") from None
        torch.set_rng_state(torch.tensor(arrays["torch.rng"]))
        self.shuffle.set_state(torch.tensor(arrays["torch.shuffle"]))
        self.iteration, self.env_transitions = counters["iteration"], counters["env_transitions"]
        self.wall_clock_s = counters["wall_clock_s"]

    def run(
        self,
        on_iteration: Callable[[dict[str, float]], None] | None = None,
        running: Callable[[], bool] = always,
    ) -> Path:
        """Iterate until a budget is spent or `running()` turns False (on any rank: all stop
        together); returns the metrics file. `on_iteration` sees every iteration's metrics (a
        publisher, a test). Only the main rank writes metrics, logs and checkpoints.

        With one rank, `running()` turning False also stops the iteration under way, between
        two steps of its rollout or two minibatches of its update: the run then goes back to
        where that iteration began (a snapshot kept in memory), so the checkpoint it writes
        is the state after its last whole iteration and `--resume` continues exactly from it.
        Several ranks finish the iteration together (their collectives must not part)."""
        config, main = self.config, self.ranks.main
        started = last_log = last_checkpoint = time.monotonic()
        before = self.wall_clock_s  # a resumed run's budget counts its earlier time too
        inner = running if self.ranks.size == 1 else always
        with contextlib.ExitStack() as stack:
            metrics = stack.enter_context(self.metrics_path.open("a")) if main else None
            while self.ranks.all(running() and self.env_transitions < config.max_env_transitions
                                 and before + time.monotonic() - started < config.max_wall_clock_s):  # fmt: skip
                boundary = self.state() if inner is not always else None
                try:
                    row = self.iterate(inner)
                except InterruptedError:  # stopped mid-iteration, or while waiting for workers
                    if boundary is not None:
                        self.load_state(boundary)
                    self.interrupted = True
                    break
                self.wall_clock_s = before + time.monotonic() - started
                row = self.last_row = {**row, "wall_clock_s": self.wall_clock_s}
                if metrics is not None:
                    metrics.write(json.dumps(row) + "\n")
                    metrics.flush()
                if on_iteration is not None:
                    on_iteration(row)
                if not main:
                    continue
                now = time.monotonic()
                if now - last_log >= config.log_period_s:
                    log.info(self.progress(row))
                    last_log = now
                if now - last_checkpoint >= config.checkpoint_period_s:
                    self.checkpoint()
                    last_checkpoint = now
        if main:
            self.checkpoint()
        return self.metrics_path


def read_snapshot(config: RunConfig) -> tuple[Arrays, dict[str, Any]]:
    """The snapshot in `config.run_dir`, once it is known to be of this run (ResumeError)."""
    arrays, meta = resume.read(config.run_dir / "checkpoints")
    resume.check_identity(meta["run"], config.identity, config.run_dir)
    return arrays, meta


def progress_line(row: dict[str, float]) -> str:
    """One line a person reads while the run goes on."""
    return (
        f"it {row['iteration']} | {row['env_transitions'] / 1e6:.2f}M transitions | "
        f"{row['env_steps_per_s']:.0f} env steps/s | success {row['success_rate']:.2f} over "
        f"{row['episodes']} episodes | return {row.get('return/total', math.nan):.3f} | "
        f"kl {row['approx_kl']:.4f} | clip {row['clip_fraction']:.2f} | grad agreement "
        f"{row['gradient_agreement']:.3f} | lr {row['learning_rate']:.1e} | log std {row['log_std']:.2f}"
        f"{workers_progress(row)}"
    )
