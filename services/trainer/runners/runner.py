"""The training loop: collect a rollout, let the run's algorithm learn from it, advance
the one schedule counter, log, checkpoint.

Rollouts come from a `RolloutSource`: the algorithm's in-process collection by default (PPO:
`InProcess` runs the sim, perception, policy and the safety filter's training profile through
`RolloutWorker` in this process, `hamnet trainer --inprocess`; DAgger: `InProcessDagger`) or
`hamnet.trainer.collection.streamed.Streamed`, which announces the weights and gathers chunks
from rollout workers over Zenoh (`hamnet trainer`). What is learned is the `Algorithm`'s
(`hamnet.trainer.algorithms`: PPO by default, or DAgger): one loop, checkpoints, snapshots
and metrics file for both. The policy's input statistics (`InputNormalizer`, saved with its
weights) take in each rollout's observations after the update.
Per iteration one JSON line goes to `<run_dir>/metrics.jsonl`; a progress line goes to the
log every `log_period_s`.
"""

from __future__ import annotations

import contextlib
import copy
import json
import logging
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from hamnet.policy.policy import Policy
from hamnet.policy.registry import build, with_changes
from hamnet.policy.weights import load_into, read_checkpoint, save_checkpoint
from hamnet.runtime.runs import command_line
from hamnet.task.rewards import REWARD_NAMES
from hamnet.trainer.algorithms.algorithm import Algorithm
from hamnet.trainer.algorithms.ppo_learner import PPO
from hamnet.trainer.collection.sources import RolloutSource
from hamnet.trainer.runners import snapshots
from hamnet.trainer.runners.episodes import EpisodeTracker
from hamnet.trainer.runners.ranks import ONE, Ranks
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.snapshots import Arrays, Resumable, ResumeError, Snapshot, nest, part
from hamnet.trainer.runners.stopping import always

log = logging.getLogger(__name__)


class Runner:
    """Owns the run: rollout source, policy, algorithm, episode statistics, counters."""

    def __init__(
        self,
        config: RunConfig,
        source: Callable[[Policy], RolloutSource] | None = None,
        resume: bool = False,
        ranks: Ranks = ONE,
        algorithm: Algorithm | None = None,
    ) -> None:
        """`algorithm` learns (default PPO on `config`); `source(policy)` makes the rollout
        source for the run's policy (default the algorithm's in-process collection).
        With `resume`, continue from the snapshot in `config.run_dir` (`hamnet.trainer.runners.snapshots`);
        ResumeError when there is none or it is of another run, before anything is built.
        With several `ranks` this process learns from its source's environments, the others
        from theirs (`hamnet.trainer.runners.ranks`); only the main rank writes metrics and
        checkpoints. ValueError when the algorithm cannot run `config`."""
        self.algorithm = PPO(config) if algorithm is None else algorithm
        config = self.algorithm.prepare(config)
        self.config, self.ranks = config, ranks
        saved = snapshots.read_run(config.run_dir, config.identity) if resume else None
        torch.set_num_threads(1)
        self.policy = build(
            config.architecture,
            with_changes(
                config.architecture,
                log_std=config.log_std,
                init=config.init,
                shared_value_gradient=config.shared_value_gradient,
                action_space=config.action_space,
                pose_readings=config.pose_readings,
            ),
            config.seed,
        )
        self.source = self.algorithm.in_process(config) if source is None else source(self.policy)
        cores = max(1, (os.cpu_count() or 1) // ranks.size)  # ranks share the machine
        self.learner_threads = config.learner_threads or (
            cores if self.source.alone_in_update else 1
        )
        """Torch threads of the update (`RunConfig.learner_threads`, resolved)."""
        # After the source: every rank subscribes to its workers' chunks before the main one
        # announces the first weights.
        ranks.broadcast(self.policy)
        envs = self.source.num_envs * ranks.size  # every rank's: they see them all
        self.algorithm.start(self.policy, envs, ranks, self.learner_threads)
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
        self.commands = [command_line("trainer")]
        """The command lines that made the run: its start, then each resume (a snapshot
        carries them, so a resumed run's summary says how to repeat all of it)."""
        config.run_dir.mkdir(parents=True, exist_ok=True)
        self.metrics_path = config.run_dir / "metrics.jsonl"
        if saved is not None:
            self.restore(*saved)

    @property
    def version(self) -> int:
        """Version of the current weights: the updates made so far plus one."""
        return self.iteration + 1

    def iterate(self, running: Callable[[], bool] = always) -> dict[str, float]:
        """One rollout and one update of the algorithm; returns that iteration's metrics.
        InterruptedError, with the iteration half done, once `running()` turns False (`run`
        goes back to before it)."""
        started = time.perf_counter()
        config, policy = self.config, self.policy
        policy.set_env_transitions(self.env_transitions)
        policy.eval()
        collected = self.source.collect(
            policy, config.rollout_steps, self.env_transitions, self.version, running
        )
        collect_done = time.perf_counter()
        whole = self.ranks.environments(collected.rollout)
        self.tracker.add(whole, collected.envs)
        learned = self.algorithm.learn(collected, whole, self.env_transitions, running)
        policy.normalizer.update(whole.inputs.observation)  # after: act and learn agreed
        transitions = whole.rewards.shape[0] * whole.rewards.shape[1]
        return {
            **self.advance(transitions, started, collect_done),
            **learned,
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

    @property
    def checkpoints(self) -> Path:
        """Where the run's checkpoint and snapshot go."""
        return self.config.run_dir / "checkpoints"

    def checkpoint(self) -> Path:
        """Write the policy's weights (loadable by `hamnet policy --checkpoint`) and the rest
        of the run's snapshot (`hamnet.trainer.runners.snapshots`); returns the weights' path."""
        path = self.checkpoints / "latest.safetensors"
        path.parent.mkdir(parents=True, exist_ok=True)
        snapshots.write(self.checkpoints, self.snapshot())
        save_checkpoint(path, self.policy, self.version)
        return path

    def snapshot(self) -> Snapshot:
        """Everything but the policy's weights that the run continues from: the algorithm's
        part (PPO: Adam's state and rate, reward scaler, minibatches' generator; DAgger: Adam's
        state and the teacher's identity), the episode tracker, torch's global RNG, counters,
        the run's identity and, from an in-process source, every worker's state."""
        parts = {
            "algorithm": self.algorithm.snapshot(),
            "tracker": self.tracker.snapshot(),
            "torch": ({"rng": torch.get_rng_state()}, {}),
        }
        if isinstance(self.source, Resumable):  # streamed: the workers simply go on
            parts["source"] = self.source.snapshot()
        arrays, meta = nest(parts)
        counters = {
            "iteration": self.iteration,
            "env_transitions": self.env_transitions,
            "wall_clock_s": self.wall_clock_s,
        }
        return arrays, {
            **meta,
            "counters": counters,
            "run": snapshots.as_json(self.config.identity),
            "algo": self.algorithm.name,
            "commands": self.commands,
        }

    def state(self) -> Snapshot:
        """The whole run in memory, copied: its snapshot and the policy's weights (read-only
        arrays, which nothing changes in place, as they are)."""
        arrays, meta = self.snapshot()
        weights = {f"policy.{name}": value for name, value in self.policy.state_dict().items()}
        copied = {
            name: value.clone()
            if isinstance(value, torch.Tensor)
            else value
            if isinstance(value, np.ndarray) and not value.flags.writeable
            else np.array(value)
            for name, value in {**arrays, **weights}.items()
        }
        return copied, copy.deepcopy(meta)

    def load_state(self, state: Snapshot) -> None:
        """Go back to `state` (from `state()`): the weights, then the snapshot's parts."""
        arrays, meta = state
        prefix = "policy."
        self.policy.load_state_dict(
            {
                name[len(prefix) :]: value
                for name, value in arrays.items()
                if name.startswith(prefix)
            }
        )
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
                raise ResumeError(
                    f"weights of version {weights.version}, the snapshot is of "
                    f"iteration {iteration} (a write was cut short)"
                )
            load_into(self.policy, weights)
        except ValueError as error:
            raise ResumeError(f"cannot resume {self.config.run_dir}: {error}") from None
        self.restore_parts(arrays, meta)
        # Snapshots written before the commands were recorded carry none.
        self.commands = [*meta.get("commands", []), *self.commands[-1:]]
        if self.ranks.main:
            snapshots.trim_metrics(self.metrics_path, self.iteration)

    def restore_parts(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Everything of a snapshot but the weights: the algorithm's part, tracker, source,
        random generator and counters (ResumeError when a part does not fit or the snapshot
        is of another algorithm)."""
        counters = meta["counters"]
        try:
            if meta.get("algo") != self.algorithm.name:
                raise ResumeError(f"it is not a {self.algorithm.name} run")
            self.algorithm.restore(*part(arrays, meta, "algorithm"))
            self.tracker.restore(*part(arrays, meta, "tracker"))
            if "source" in meta and isinstance(self.source, Resumable):
                self.source.restore(*part(arrays, meta, "source"))
        except ValueError as error:
            raise ResumeError(f"cannot resume {self.config.run_dir}: {error}") from None
        torch.set_rng_state(torch.tensor(arrays["torch.rng"]))
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

        With one rank, `running()` turning False or the wall-clock budget running out also
        stops the iteration under way, between two steps of its rollout or two minibatches
        of its update: the run then goes back to where that iteration began (a snapshot kept
        in memory), so the checkpoint it writes is the state after its last whole iteration,
        `--resume` continues exactly from it, and a run's `wall_clock_s` never passes its
        budget (a result claimed within the hour is the policy of the hour). Several ranks
        finish the iteration together (their collectives must not part), so they may pass
        the budget by one iteration."""
        config, main = self.config, self.ranks.main
        started = last_log = last_checkpoint = time.monotonic()
        before = self.wall_clock_s  # a resumed run's budget counts its earlier time too
        deadline = started + config.max_wall_clock_s - before

        def within_budget() -> bool:
            return running() and time.monotonic() < deadline

        inner = within_budget if self.ranks.size == 1 else always
        with contextlib.ExitStack() as stack:
            metrics = stack.enter_context(self.metrics_path.open("a")) if main else None
            while self.ranks.all(
                within_budget() and self.env_transitions < config.max_env_transitions
            ):
                boundary = self.state() if inner is not always else None
                try:
                    row = self.iterate(inner)
                    ended = time.monotonic()
                    if inner is not always and ended >= deadline:
                        raise InterruptedError("the iteration ended past the wall-clock budget")
                except InterruptedError:  # stopped mid-iteration, or while waiting for workers
                    if boundary is not None:
                        self.load_state(boundary)
                    self.interrupted = True
                    if running():
                        log.info("wall-clock budget of %.0f s spent: iteration %d, which did "
                                 "not end within it, is dropped", config.max_wall_clock_s,
                                 self.iteration + 1)  # fmt: skip
                    break
                self.wall_clock_s = before + ended - started
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
                    log.info(self.algorithm.progress(row))
                    last_log = now
                if now - last_checkpoint >= config.checkpoint_period_s:
                    self.checkpoint()
                    last_checkpoint = now
        if main:
            self.checkpoint()
        return self.metrics_path
